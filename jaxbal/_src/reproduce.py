"""Discover and run the experiments of ``experiments/``; write CSVs, PNGs and REPORT.md.

An experiment is a Python file in ``experiments/`` defining ``EXPERIMENT``, an
:class:`jaxbal.report.Experiment`. Experiments are thin: parameters, calls into
jaxbal, a table and a plot.
"""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path

from tqdm.auto import tqdm

from jaxbal._src.report import (
    Context,
    Experiment,
    atomic_write_text,
    release_compiled_programs,
    render_report,
    render_summary,
)

README_START = "<!-- results:start -->"
README_END = "<!-- results:end -->"


def experiments_dir() -> Path:
    """The repository's ``experiments/`` folder: next to the ``jaxbal`` package (an
    editable install, from any directory), else in the current directory.

    Raises:
        FileNotFoundError: neither exists (an install from a wheel carries no
            experiments: run from a clone of the repository).
    """
    package = Path(__file__).resolve().parent.parent  # jaxbal/_src/reproduce.py -> jaxbal/
    for folder in (package.parent / "experiments", Path.cwd() / "experiments"):
        if folder.is_dir():
            return folder
    raise FileNotFoundError(
        f"no experiments/ folder next to the jaxbal package ({package.parent}) or in the "
        "current directory: run from a clone of the repository (pip install -e .)"
    )


def discover(folder: Path | None = None) -> list[Experiment]:
    """All experiments, sorted by file name."""
    folder = folder or experiments_dir()
    found = []
    for path in sorted(folder.glob("*.py")):
        if path.name.startswith("_"):
            continue
        spec = importlib.util.spec_from_file_location(f"jaxbal_experiments.{path.stem}", path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        experiment = getattr(module, "EXPERIMENT", None)
        if isinstance(experiment, Experiment):
            found.append(experiment)
    return found


def select(only: str | None) -> list[Experiment]:
    """The experiments whose name contains ``only`` (all for ``None``).

    Raises:
        ValueError: ``only`` is empty or matches nothing (the message lists the names).
    """
    experiments = discover()
    if only is None:
        return experiments
    chosen = [e for e in experiments if only.strip() and only.strip() in e.name]
    if not chosen:
        names = ", ".join(e.name for e in experiments)
        raise ValueError(f"no experiment matches --only {only!r}; choose from: {names}")
    return chosen


def run_all(out: Path, only: str | None = None, update_readme: Path | None = None):
    """Run the experiments (those whose name contains ``only``, if given) into ``out``."""
    out = Path(out)
    experiments = select(only)
    out.mkdir(parents=True, exist_ok=True)
    results = []
    with tqdm(total=len(experiments), desc="reproduce", unit="exp") as bar:
        for experiment in experiments:
            bar.set_postfix_str(experiment.name)
            context = Context(out=out, progress=lambda msg: bar.set_postfix_str(msg))
            result = experiment.run(context)
            for table in result.tables:
                atomic_write_text(out / f"{table.id}.csv", table.to_csv())
            results.append((experiment, result))
            release_compiled_programs()
            bar.update(1)
    atomic_write_text(out / "REPORT.md", render_report(results))
    summary = render_summary(results)
    atomic_write_text(out / "SUMMARY.md", summary + "\n")
    if update_readme is not None and only is None and Path(update_readme).exists():
        text = Path(update_readme).read_text()
        pattern = re.compile(re.escape(README_START) + ".*?" + re.escape(README_END), re.S)
        if pattern.search(text):
            block = f"{README_START}\n{summary}\n{README_END}"
            atomic_write_text(Path(update_readme), pattern.sub(lambda _: block, text))
    return results
