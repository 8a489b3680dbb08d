"""Counter-mass co-design for every robot (placeholder: see jaxbal._src.design)."""
