"""The README's ten-line example runs and prints the paper's P5P9 case-2 force (Table 1,
44.3 N, within 1 %); its sweep example (≤ 10 lines) runs, writes its store and plot, and
finds the DUAL-V's balanced counter-mass (7.983 kg, the robot's own design) at no payload;
its base-vibration example leaves the base at rest without added mass."""

import contextlib
import io
import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parent.parent / "README.md"


def test_readme_example_runs():
    code = re.search(r"```python\n(.*?)```", README.read_text(), re.S).group(1)
    output = io.StringIO()
    with contextlib.redirect_stdout(output):
        exec(compile(code, "README.md", "exec"), {})
    assert abs(float(output.getvalue().split()[0]) / 44.3 - 1) < 0.01


def test_readme_balancing_example_prints_its_conditions():
    """The balancing example prints the four conditions and residuals the README shows."""
    text = README.read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    code = next(b for b in blocks if "# balancing example" in b)
    shown = text[text.index(code) + len(code) :].split("```\n")[2]
    output = io.StringIO()
    with contextlib.redirect_stdout(output):
        exec(compile(code, "README.md", "exec"), {})
    assert output.getvalue().strip() == shown.strip()


@pytest.mark.slow
def test_readme_results_block_equals_a_fresh_reproduction(tmp_path):
    """The README quotes what `make reproduce` generates: run every experiment into a
    temporary folder and compare its SUMMARY.md with the README's results block."""
    from jaxbal._src.reproduce import README_END, README_START, run_all

    run_all(tmp_path)
    text = README.read_text()
    block = text[text.index(README_START) + len(README_START) : text.index(README_END)]
    assert block.strip() == (tmp_path / "SUMMARY.md").read_text().strip()


@pytest.mark.slow
def test_readme_sweep_example_runs_in_ten_lines(tmp_path, monkeypatch):
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), re.S)
    code = next(b for b in blocks if "# sweep example" in b)
    assert len(code.strip().splitlines()) <= 10
    monkeypatch.chdir(tmp_path)
    scope = {}
    exec(compile(code, "README.md", "exec"), scope)
    ds = scope["ds"]
    assert ds["value"].dims == ("counter_mass", "payload")
    assert ds["value"].attrs["units"] == "N" and ds["payload"].attrs["units"] == "kg"
    best = float(ds["counter_mass"][ds["value"].sel(payload=0.0).argmin(dim="counter_mass")])
    assert best == 8.0  # the grid point nearest 7.983 kg, where the robot is balanced
    assert (tmp_path / "dual_v.zarr").is_dir()
    assert (tmp_path / "dual_v_peak_force.png").stat().st_size > 1000


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_readme_vibration_example_leaves_the_base_at_rest():
    """The README's example: the shaped trapezoid's residual vibration is < 1e-9 of the
    starting one, with no added mass (nothing else is free)."""
    import jax.numpy as jnp

    text = README.read_text()
    code = next(b for b in re.findall(r"```python\n(.*?)```", text, re.S) if "# vibration" in b)
    scope = {}
    with contextlib.redirect_stdout(io.StringIO()):
        exec(compile(code, "README.md", "exec"), scope)
    before, after = scope["best"].metrics["residual_vibration"]
    assert after < 1e-9 * before and before > 1e-4
    assert float(jnp.sum(scope["best"].robot.counter_masses)) == 0.0
