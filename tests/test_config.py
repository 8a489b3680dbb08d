"""jaxbal's configuration: float64 and the persistent compilation cache (checked in
fresh interpreters, since the test session turns the cache off in conftest.py)."""

import json
import os
import subprocess
import sys

import pytest

SCRIPT = """
import json, sys, jax, jax.numpy as jnp
import jaxbal
from jaxbal._src import config
if sys.argv[1:] == ["compile"]:  # something for the cache to keep
    robot = jaxbal.robots.planar_2r()
    wrench = jax.jit(lambda q: jaxbal.shaking_wrench(robot, q, q, q)[0])
    jax.block_until_ready(wrench(jnp.ones(2)))
print(json.dumps({"x64": jax.config.jax_enable_x64,
                  "dir": jax.config.jax_compilation_cache_dir,
                  "chosen": str(config.cache_dir())}))
"""


def _run(tmp_path, cache_env, compile=False):
    env = dict(os.environ)
    env.pop("JAXBAL_CACHE_DIR", None)
    env.pop("JAX_COMPILATION_CACHE_DIR", None)
    env["XDG_CACHE_HOME"] = str(tmp_path / "xdg")
    if cache_env is not None:
        env["JAXBAL_CACHE_DIR"] = cache_env
    out = subprocess.run(
        [sys.executable, "-c", SCRIPT] + ["compile"] * compile,
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_default_cache_is_in_the_user_cache_dir_and_is_written(tmp_path):
    result = _run(tmp_path, None, compile=True)
    expected = tmp_path / "xdg" / "jaxbal" / "jax"
    assert result["x64"] is True
    assert result["dir"] == str(expected)
    assert any(expected.iterdir())  # the compiled wrench was persisted


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_cache_directory_override_and_off(tmp_path):
    chosen = tmp_path / "mine"
    assert _run(tmp_path, str(chosen))["dir"] == str(chosen)
    off = _run(tmp_path, "off")
    assert off["chosen"] == "None" and not off["dir"]
