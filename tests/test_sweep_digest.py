"""The code fingerprint of a resumable sweep sees the globals a metric reads.

A metric reading a module-level pytree (a base model, a profile) or a constant of an
imported module (``config.SCALE``) was fingerprinted without it: editing that constant
between a killed run and its resume was accepted, and the store mixed the two sweeps.
So was a config object read as a global (a dataclass, a ``types.SimpleNamespace``, a
``functools.partial``; /tmp/ut_sweep/t20_stale_global.py); one the digest cannot
represent is now refused by name.
"""

import os
import subprocess
import sys
import textwrap
import types

import equinox as eqx
import pytest

from jaxbal._src.sweep_digest import value_digest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

SOURCE = """
import jax
import jaxbal
from jaxbal.profiles import BangBang, Quintic
PROFILE = Quintic()
ROBOT = jaxbal.robots.planar_2r()

def by_module(robot, motion):
    return config.SCALE * robot.payload

def by_pytree(robot, motion):
    return PROFILE(0.3) * ROBOT.payload

@jax.jit
def helper(x):
    return 2.0 * x

def by_jitted_helper(robot, motion):
    return helper(robot.payload)
"""


def _user():
    """The functions of ``SOURCE`` in a fresh module, reading a fresh ``config``."""
    config = types.ModuleType("config")
    config.SCALE = 1.0
    user = types.ModuleType("user_metrics")
    user.config = config
    exec(SOURCE, user.__dict__)  # noqa: S102
    return user, config


def test_a_constant_of_an_imported_module_enters_the_digest():
    user, config = _user()
    before = value_digest(user.by_module)
    config.SCALE = 1000.0
    assert value_digest(user.by_module) != before
    config.SCALE = 1.0
    assert value_digest(user.by_module) == before


def test_a_module_level_pytree_enters_the_digest():
    from jaxbal.profiles import BangBang

    user, _ = _user()
    before = value_digest(user.by_pytree)
    user.PROFILE = BangBang()
    assert value_digest(user.by_pytree) != before
    user.PROFILE = user.Quintic()
    assert value_digest(user.by_pytree) == before
    user.ROBOT = eqx.tree_at(lambda r: r.payload, user.ROBOT, 1.0)
    assert value_digest(user.by_pytree) != before


def test_a_jitted_helper_of_the_module_enters_by_its_code():
    user, _ = _user()
    before = value_digest(user.by_jitted_helper)
    exec("@jax.jit\ndef helper(x):\n    return 3.0 * x\n", user.__dict__)  # noqa: S102
    assert value_digest(user.by_jitted_helper) != before


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_the_digest_is_the_same_in_another_process():
    """Pytree globals and module constants are hashed by content: no address, salted
    hash or object id enters (another ``PYTHONHASHSEED``)."""
    script = textwrap.dedent(f"""
        import sys, types
        sys.path.insert(0, {os.path.join(ROOT, "tests")!r})
        from test_sweep_digest import _user
        from jaxbal._src.sweep_digest import value_digest
        user, _ = _user()
        print(*(value_digest(f) for f in (user.by_module, user.by_pytree, user.by_jitted_helper)))
    """)
    env = {**os.environ, "PYTHONHASHSEED": "12345", "JAXBAL_CACHE_DIR": "off"}
    env["PYTHONPATH"] = ROOT + os.pathsep + env.get("PYTHONPATH", "")
    out = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True,
                         text=True, timeout=300)  # fmt: skip
    assert out.returncode == 0, out.stderr[-3000:]
    user, _ = _user()
    here = [value_digest(f) for f in (user.by_module, user.by_pytree, user.by_jitted_helper)]
    assert out.stdout.split()[-3:] == here


CONFIGS = """
import dataclasses, functools, types
import numpy as np

@dataclasses.dataclass
class Config:
    scale: float
    table: np.ndarray

class Plain:  # object.__repr__: shows no content
    def __init__(self, scale):
        self.scale = scale

CFG = Config(1.0, np.zeros(2000))  # a repr would abbreviate the array
NS = types.SimpleNamespace(scale=1.0)
def helper(x, k):
    return k * x
PART = functools.partial(helper, k=1.0)
PLAIN = Plain(1.0)

def by_dataclass(robot, motion):
    return CFG.scale * robot.payload + CFG.table[1000]

def by_namespace(robot, motion):
    return NS.scale * robot.payload

def by_partial(robot, motion):
    return PART(robot.payload)

def by_plain(robot, motion):
    return PLAIN.scale * robot.payload

def by_attribute(robot, motion):  # ``PLAIN`` named as an attribute, not read as a global
    return robot.PLAIN
"""


def _configs():
    user = types.ModuleType("user_configs")
    exec(CONFIGS, user.__dict__)  # noqa: S102
    return user


def test_a_config_object_read_as_a_global_enters_the_digest():
    """A dataclass instance, a namespace and a partial read as globals were skipped: a
    store resumed after editing one mixed the old and the new values."""
    user = _configs()
    edits = {
        "by_dataclass": lambda: user.CFG.table.__setitem__(1000, 1.0),
        "by_namespace": lambda: setattr(user.NS, "scale", 2.0),
        "by_partial": lambda: setattr(user, "PART", user.functools.partial(user.helper, k=2.0)),
    }
    for name, edit in edits.items():
        before = value_digest(getattr(user, name))
        edit()
        assert value_digest(getattr(user, name)) != before, name
    user = _configs()
    assert value_digest(user.by_dataclass) == value_digest(_configs().by_dataclass)


def test_a_global_the_digest_cannot_represent_is_refused_by_name():
    user = _configs()
    message = r"by_plain reads the global 'PLAIN', a user_configs\.Plain that .* cannot rep"
    with pytest.raises(ValueError, match=message + r"resent.*make it a dataclass"):
        value_digest(user.by_plain)
    value_digest(user.by_attribute)  # an attribute of that name is no global
