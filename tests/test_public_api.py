"""The package's shape: public index, no import cycle, small files, thin experiments.

Each check is structural (it reads the source tree or imports modules in a fresh
interpreter), so it fails as soon as a change breaks the layout the README promises.
"""

import ast
import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "jaxbal"
PUBLIC_MODULES = (
    "jaxbal",
    "jaxbal.robots",
    "jaxbal.robots.planar_arm",
    "jaxbal.robots.scara_balancing",
    "jaxbal.robots.dual_v_balancing",
    "jaxbal.robots.dual_v_dynamics",
    "jaxbal.robots.dual_v_plots",
    "jaxbal.robots.orthoglide_planning",
    "jaxbal.robots.planar_arm_studies",
    "jaxbal.robots.scara_studies",
    "jaxbal.robots.dual_v_studies",
    "jaxbal.robots.orthoglide_studies",
    "jaxbal.robots.mjcf_balancing",
    "jaxbal.profiles",
    "jaxbal.planning",
    "jaxbal.design",
    "jaxbal.balancing",
    "jaxbal.sensitivity",
    "jaxbal.vibration",
    "jaxbal.mujoco",
    "jaxbal.report",
)
MAX_LINES = 400
MAX_EXPERIMENT_LINES = 200


def _library_files():
    return sorted(PACKAGE.rglob("*.py"))


def _module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


#: run in a fresh interpreter: the third-party dependencies are imported once, then each
#: module is imported in a forked child in which no jaxbal module is loaded yet
_IMPORT_EACH_ALONE = """
import importlib, os, sys, traceback
for name in ("numpy", "scipy", "jax", "jax.numpy", "equinox", "optax", "jaxtyping",
             "mujoco", "mujoco.mjx", "typer"):
    try:
        importlib.import_module(name)
    except ImportError:
        pass
assert not [m for m in sys.modules if m == "jaxbal" or m.startswith("jaxbal.")]


def alone(module, report=None):
    pid = os.fork()
    if pid == 0:
        try:
            importlib.import_module(module)
        except BaseException:
            print(f"--- {module}", file=sys.stderr)
            traceback.print_exc()
            sys.stderr.flush()
            os._exit(1)
        if report is not None:  # the modules this import loaded, for the parent
            os.write(report, " ".join(m for m in sys.modules if m.startswith("jaxbal")).encode())
        os._exit(0)
    return os.waitpid(pid, 0)[1] == 0


read, write = os.pipe()
failed = [] if alone("jaxbal", write) else ["jaxbal"]
os.close(write)
with os.fdopen(read) as pipe:
    loaded = set(pipe.read().split())
# importing jaxbal.X runs jaxbal/__init__ to its end first (Python imports the package
# first), so every module that ``import jaxbal`` loads is loaded in that order whatever
# X: only the others need a fork of their own (forked from this process, which has not
# started JAX's runtime: a fork after ``import jaxbal`` could deadlock in its threads)
rest = [m for m in sys.argv[1:] if m not in loaded]
failed += [m for m in rest if not alone(m)]
print("alone:", rest, "failed:", failed)
sys.exit(1 if failed else 0)
"""


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_each_public_module_imports_alone():
    """Each module is imported first in an interpreter without any jaxbal module (a
    fork of one that holds only the third-party dependencies, so that the checks cost
    one start of JAX), so an import cycle (a module that needs another one
    half-initialised) fails here whatever the import order elsewhere. ``jaxbal``
    comes first; the modules it loads are loaded in its order whatever module is asked
    for, the others (``jaxbal.mujoco``, ``jaxbal.report``, the robots' studies, the
    CLI …) each get a fork."""
    modules = PUBLIC_MODULES + ("jaxbal._src.robots", "jaxbal._src.cli")
    command = [sys.executable, "-c", _IMPORT_EACH_ALONE, *modules]
    result = subprocess.run(command, capture_output=True, text=True, cwd=ROOT)
    assert result.returncode == 0, result.stdout[-1000:] + result.stderr[-4000:]
    assert "'jaxbal.mujoco'" in result.stdout, result.stdout  # the lazy ones were checked


def test_no_import_cycle_between_library_modules():
    """The graph of module-level ``jaxbal`` imports inside the package is acyclic."""
    modules = {_module_name(p): p for p in _library_files()}
    graph = {}
    for name, path in modules.items():
        tree = ast.parse(path.read_text())
        targets = set()
        for node in tree.body:  # module level only: imports inside functions are lazy
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                if node.module.startswith("jaxbal"):
                    targets.add(node.module)
                    for alias in node.names:
                        if f"{node.module}.{alias.name}" in modules:
                            targets.add(f"{node.module}.{alias.name}")
            elif isinstance(node, ast.Import):
                targets |= {a.name for a in node.names if a.name.startswith("jaxbal")}
        graph[name] = {t for t in targets if t in modules and t != name}
    # the package __init__ re-exports submodules; edges *into* a package __init__ from
    # its own submodules would be cycles, edges out of it are the public index.
    state = {}

    def visit(node, stack):
        state[node] = "active"
        for target in graph[node]:
            if state.get(target) == "active":
                raise AssertionError(f"import cycle: {' -> '.join(stack + [node, target])}")
            if target not in state:
                visit(target, stack + [node])
        state[node] = "done"

    for node in graph:
        if node not in state:
            visit(node, [])


@pytest.mark.parametrize("path", _library_files(), ids=lambda p: str(p.relative_to(ROOT)))
def test_library_files_are_small(path):
    assert len(path.read_text().splitlines()) <= MAX_LINES


def _experiment_files():
    return sorted((ROOT / "experiments").glob("*.py"))


@pytest.mark.parametrize("path", _experiment_files(), ids=lambda p: p.name)
def test_experiments_are_thin_and_public(path):
    """Experiments: ≤ 200 lines, only the public API, no optimiser loop of their own."""
    text = path.read_text()
    assert len(text.splitlines()) <= MAX_EXPERIMENT_LINES
    assert "jaxbal._src" not in text
    for forbidden in ("optax.", "jax.lax.while_loop", "fori_loop"):
        assert forbidden not in text, forbidden


def _notebook_sources():
    for path in sorted((ROOT / "notebooks").glob("*.ipynb")):
        cells = json.loads(path.read_text())["cells"]
        yield path, "\n".join("".join(c["source"]) for c in cells if c["cell_type"] == "code")


@pytest.mark.parametrize(
    "path,source", list(_notebook_sources()), ids=lambda v: getattr(v, "name", "")
)
def test_notebooks_and_benchmarks_use_the_public_api(path, source):
    assert "jaxbal._src" not in source


def test_benchmark_uses_the_public_api():
    assert "jaxbal._src" not in (ROOT / "benchmarks" / "run.py").read_text()


def test_no_jit_of_a_fresh_lambda_inside_the_library():
    """jit at the boundary: a ``jax.jit(lambda …)`` inside a library function would be
    recompiled at every call."""
    offenders = []
    for path in _library_files():
        for number, line in enumerate(path.read_text().splitlines(), 1):
            if "jit(lambda" in line.replace(" ", "") or "jit(functools.partial" in line:
                offenders.append(f"{path.relative_to(ROOT)}:{number}")
    assert not offenders


def test_shared_helpers_exist_once():
    """Unit vectors, angle wrapping, skew matrices and two-link IK live in linalg only."""
    helpers = ("def _unit(", "def _wrap(", "def _skew(", "def unit(", "def wrap(", "def skew(")
    for path in _library_files():
        if path.name == "linalg.py":
            continue
        text = path.read_text()
        for helper in helpers:
            assert helper not in text, f"{path.relative_to(ROOT)} defines {helper}"
        assert "arccos(jnp.clip(cos_q2" not in text, f"{path} copies the two-link IK"
