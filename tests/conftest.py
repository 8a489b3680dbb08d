"""Test configuration: float64 on (jaxbal does it on import), strict dtype promotion off."""

import jax

import jaxbal  # noqa: F401  (enables float64)

jax.config.update("jax_enable_x64", True)
