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

**Compiler options.** :func:`compiler_options` gives the XLA options of jaxbal's
programs that run many times in one dispatch or are compiled on every first call (the
co-design's): an LLVM optimisation level and, where this jaxlib knows it,
``xla_cpu_use_fusion_emitters=False`` (XLA:CPU's older elemental emitters). Measured on
the 2-core CPU, the emitters are most of a small program's compile time: the compiled
co-design of a 20-variable arm (``benchmarks/codesign_bench.py``) compiled in 0.29 s
instead of 0.67 s at level 0, running as fast (5.7 ms either way).
"""

import os
from functools import cache
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


def _plus_one(x):
    return x + 1.0


@cache
def _knows_fusion_emitter_option() -> bool:
    """Whether this jaxlib accepts ``xla_cpu_use_fusion_emitters`` (probed once, by
    compiling a one-operation program)."""
    try:
        options = {"xla_cpu_use_fusion_emitters": False}
        jax.jit(_plus_one, compiler_options=options).lower(1.0).compile()
    except Exception:  # noqa: BLE001 - an unknown option: XLA's error type varies
        return False
    return True


def compiler_options(level: int) -> dict:
    """XLA compiler options of a jaxbal program (module doc): LLVM's optimisation
    ``level`` (0–3) and the elemental emitters where available. Read when a program is
    first compiled, so that importing jaxbal compiles nothing."""
    options = {"xla_backend_optimization_level": level}
    if _knows_fusion_emitter_option():
        options["xla_cpu_use_fusion_emitters"] = False
    return options


enable_compilation_cache()
