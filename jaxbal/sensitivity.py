"""Design sensitivities for every robot (placeholder: see jaxbal._src.sensitivity)."""
