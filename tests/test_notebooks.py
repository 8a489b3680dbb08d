"""Every notebook in notebooks/ runs top to bottom (public API only) and is stored
without outputs."""

import re
from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

ROOT = Path(__file__).resolve().parent.parent
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))
#: the public modules a notebook may import from (``jaxbal.robots`` with its submodules).
PUBLIC = {"robots", "planning", "profiles", "mujoco", "design", "balancing", "sensitivity",
          "report", "sweep", "vibration"}  # fmt: skip


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_is_stripped(path):
    notebook = nbformat.read(path, as_version=4)
    for cell in notebook.cells:
        if cell.cell_type == "code":
            assert not cell.outputs, f"{path.name}: outputs must be stripped in git"
            assert cell.execution_count is None, f"{path.name}: execution counts in git"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_uses_only_the_public_api(path):
    notebook = nbformat.read(path, as_version=4)
    code = "\n".join(cell.source for cell in notebook.cells if cell.cell_type == "code")
    assert "_src" not in code, f"{path.name}: imports private jaxbal._src"
    pattern = r"^\s*(?:from|import)\s+jaxbal\.(\w+)(?:\.(\w+))?"
    for module, submodule in re.findall(pattern, code, re.M):
        assert module in PUBLIC, f"{path.name}: jaxbal.{module} is not a public module"
        if submodule:  # a public face of jaxbal.robots (jaxbal/robots/<name>.py)
            face = ROOT / "jaxbal" / module / f"{submodule}.py"
            assert face.exists(), f"{path.name}: jaxbal.{module}.{submodule} is not public"


@pytest.mark.slow
@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_executes(path, monkeypatch):
    monkeypatch.setenv("MPLBACKEND", "Agg")
    notebook = nbformat.read(path, as_version=4)
    client = NotebookClient(
        notebook, timeout=600, kernel_name="python3", resources={"metadata": {"path": path.parent}}
    )
    client.execute()


def test_there_are_notebooks():
    assert any(p.name == "01_quickstart.ipynb" for p in NOTEBOOKS)
