"""Numerical configuration of jaxbal: float64 everywhere.

This is the one place where jaxbal switches JAX to double precision. Balancing
residuals are differences of large, nearly cancelling momenta (a perfectly balanced
robot must give a shaking force of ~1e-12 N, not ~1e-5 N), which float32 cannot
resolve. Importing :mod:`jaxbal` therefore enables ``jax_enable_x64``.
"""

import jax

jax.config.update("jax_enable_x64", True)
