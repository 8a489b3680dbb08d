"""jaxbal's implementation (private). Importing any part of it enables float64 first
(:mod:`jaxbal._src.config`), whatever the import order of the public modules: a module
constant made before that (e.g. a sign table ``jnp.array([1.0, -1.0])``) would be
float32 and turn float64 parameters made from Python floats (weakly typed) into float32.
"""

from jaxbal._src import config as _config  # noqa: F401
