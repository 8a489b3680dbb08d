"""Numerical configuration of jaxbal: float64 everywhere, and a persistent compilation
cache.

**float64.** This is the one place where jaxbal switches JAX to double precision.
Balancing residuals are differences of large, nearly cancelling momenta (a perfectly
balanced robot must give a shaking force of ~1e-12 N, not ~1e-5 N), which float32
cannot resolve. Importing :mod:`jaxbal` therefore enables ``jax_enable_x64``.

**Compilation cache.** Notebooks feel compile latency most. Importing jaxbal turns on
JAX's persistent compilation cache, so that a second Python process (a restarted
kernel, the next script of a sweep) loads compiled programs from disk instead of
compiling them again. The cache lives in ``$JAXBAL_CACHE_DIR`` if set, else
``$XDG_CACHE_HOME/jaxbal/jax`` (``~/.cache/jaxbal/jax``). Set ``JAXBAL_CACHE_DIR=off``
to leave JAX's cache settings alone; a cache directory the user already configured
for JAX (``JAX_COMPILATION_CACHE_DIR``) is respected.
"""

import os
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)


def cache_dir() -> Path | None:
    """The persistent compilation cache directory jaxbal uses (``None``: off)."""
    chosen = os.environ.get("JAXBAL_CACHE_DIR", "")
    if chosen.lower() in ("off", "0", "false", "none"):
        return None
    if chosen:
        return Path(chosen).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "jaxbal" / "jax"


def enable_compilation_cache() -> None:
    """Turn on JAX's persistent compilation cache in :func:`cache_dir` (idempotent)."""
    directory = cache_dir()
    if directory is None or jax.config.jax_compilation_cache_dir:
        return
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except OSError:  # read-only home (e.g. some clusters): run without the cache
        return
    jax.config.update("jax_compilation_cache_dir", str(directory))
    # Cache every program, also the ones that compile in a fraction of a second.
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)


enable_compilation_cache()
