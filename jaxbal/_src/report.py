"""Result tables, atomic file output and the Markdown report of ``jaxbal reproduce``.

Every published number an experiment reproduces becomes one :class:`Entry`; a
:class:`Table` of entries is written as a tidy CSV with the columns
``table,row,column,value,unit,paper,kind`` (``paper`` empty where the paper gives no
number). ``kind`` says what agreement with the paper means for that entry
(:data:`KINDS`): **predicted** (nothing was chosen using this table), **convention** (a
choice made once, documented, that this table selected), **fitted** (parameters fitted
to this table), **by construction** (the input was designed to produce it) or
**alternative reading** (a stated reading of the paper, beside the as-printed one).
Only predicted entries count as reproduced in the README summary; an entry without a
paper value is of kind ``ours only``. Files are written atomically: to a temporary
file in the same directory, then renamed, so an interrupted run never leaves a half
file.
"""

from __future__ import annotations

import csv
import gc
import io
import math
import os
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

CSV_COLUMNS = ("table", "row", "column", "value", "unit", "paper", "kind")
KINDS = ("predicted", "convention", "fitted", "by construction", "alternative reading")
#: The kind written for an entry without a published value (nothing to agree with).
OURS_ONLY = "ours only"


def atomic_write_bytes(path: Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (temp file in the same folder + rename)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


def atomic_write_text(path: Path, text: str) -> Path:
    """Text version of :func:`atomic_write_bytes` (UTF-8)."""
    return atomic_write_bytes(path, text.encode("utf-8"))


def save_figure(fig, path: Path, dpi: int = 130) -> Path:
    """Save a matplotlib figure atomically as PNG and close it."""
    import matplotlib.pyplot as plt

    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=dpi, bbox_inches="tight")
    plt.close(fig)
    return atomic_write_bytes(path, buffer.getvalue())


@dataclass(frozen=True)
class Entry:
    """One number: ours (``value``) and the paper's (``paper``, None if not given)."""

    row: str
    column: str
    value: float
    unit: str
    paper: float | None = None
    kind: str | None = None  # one of KINDS where ``paper`` is given

    @property
    def relative_difference(self) -> float | None:
        if self.paper is None or self.paper == 0 or not math.isfinite(self.value):
            return None
        return (self.value - self.paper) / abs(self.paper)


@dataclass
class Table:
    """A published table (or a summary) reproduced by an experiment."""

    id: str
    title: str
    tolerance: float | None = None  # relative tolerance used to flag misses in REPORT.md
    entries: list[Entry] = field(default_factory=list, kw_only=True)
    kind: str = field(default="predicted", kw_only=True)  # default kind of its entries

    def add(self, row, column, value, unit, paper=None, kind=None) -> None:
        """Add one entry; ``kind`` (default: the table's) is kept where ``paper`` is given."""
        kind = kind or self.kind
        if kind not in KINDS:
            raise ValueError(f"kind must be one of {KINDS}, got {kind!r}")
        self.entries.append(
            Entry(row, column, float(value), unit, paper, kind if paper is not None else None)
        )

    def mark(self, kind: str, rows=None, columns=None) -> None:
        """Set the kind of the entries with a paper value (those of ``rows`` and
        ``columns`` if given; names or predicates)."""
        if kind not in KINDS:
            raise ValueError(f"kind must be one of {KINDS}, got {kind!r}")

        def chosen(name, which):
            return which is None or (which(name) if callable(which) else name in which)

        self.entries = [
            replace(e, kind=kind)
            if e.paper is not None and chosen(e.row, rows) and chosen(e.column, columns)
            else e
            for e in self.entries
        ]

    def to_csv(self) -> str:
        buffer = io.StringIO()
        writer = csv.writer(buffer, lineterminator="\n")
        writer.writerow(CSV_COLUMNS)
        for e in self.entries:
            paper = "" if e.paper is None else repr(float(e.paper))
            kind = e.kind or OURS_ONLY
            writer.writerow([self.id, e.row, e.column, repr(float(e.value)), e.unit, paper, kind])
        return buffer.getvalue()

    def to_markdown(self) -> str:
        rows = [
            "| row | column | ours | paper | rel. diff | unit | kind |",
            "|---|---|---:|---:|---:|---|---|",
        ]
        for e in self.entries:
            rel = e.relative_difference
            flag = ""
            if rel is not None and self.tolerance is not None and abs(rel) > self.tolerance:
                flag = " ⚠"
            rel_text = "" if rel is None else f"{100 * rel:+.2f}%{flag}"
            paper = "not given" if e.paper is None else f"{e.paper:.4g}"
            rows.append(
                f"| {e.row} | {e.column} | {e.value:.4g} | {paper} | {rel_text} | {e.unit} "
                f"| {e.kind or OURS_ONLY} |"
            )
        return "\n".join(rows)

    def worst_relative_difference(self) -> float | None:
        diffs = [abs(e.relative_difference) for e in self.entries if e.relative_difference]
        return max(diffs) if diffs else None


@dataclass
class Result:
    """What one experiment produced."""

    tables: list[Table] = field(default_factory=list)
    figures: list[Path] = field(default_factory=list)
    notes: str = ""


@dataclass
class Context:
    """Handed to every experiment: where to write, and a progress callback."""

    out: Path
    progress: Callable[[str], None] = lambda message: None

    def figure_path(self, name: str) -> Path:
        return self.out / f"{name}.png"


@dataclass(frozen=True)
class Experiment:
    """An experiment: a name (``--only``), a title, and ``run(ctx) -> Result``."""

    name: str
    title: str
    run: Callable[[Context], Result]
    paper: str = ""


def render_report(results: list[tuple[Experiment, Result]]) -> str:
    """REPORT.md: for every experiment its notes, its tables (paper vs ours) and figures."""
    lines = ["# jaxbal reproduction report", ""]
    lines += [
        "Generated by `jaxbal reproduce`. ⚠ marks a relative difference above the "
        "table's stated tolerance; each is discussed in the notes of its section.",
        "",
    ]
    for experiment, result in results:
        lines += [f"## {experiment.title}", ""]
        if experiment.paper:
            lines += [f"*{experiment.paper}*", ""]
        if result.notes:
            lines += [result.notes.strip(), ""]
        for table in result.tables:
            tol = "" if table.tolerance is None else f" (tolerance {100 * table.tolerance:g}%)"
            lines += [f"### `{table.id}` — {table.title}{tol}", "", table.to_markdown(), ""]
        for figure in result.figures:
            lines += [f"![{figure.stem}]({figure.name})", ""]
    return "\n".join(lines)


def render_summary(results: list[tuple[Experiment, Result]]) -> str:
    """The short table of reproduced results quoted in README.md: per table, the
    predicted entries within tolerance apart from every other kind."""
    lines = [
        "| table | numbers | with a paper value | predicted: within tolerance "
        "| other kinds: within tolerance | worst relative difference |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for _, result in results:
        for table in result.tables:
            compared = [e for e in table.entries if e.relative_difference is not None]
            worst = table.worst_relative_difference()
            worst_text = "—" if worst is None else f"{100 * worst:.2f}%"
            predicted = [e for e in compared if e.kind == "predicted"]
            others = [e for e in compared if e.kind != "predicted"]
            within = _within(predicted, table.tolerance)
            other = _within(others, table.tolerance, kinds=True)
            lines.append(
                f"| `{table.id}` | {len(table.entries)} | {len(compared)} | {within} "
                f"| {other} | {worst_text} |"
            )
    return "\n".join(lines)


def _within(entries: list[Entry], tolerance: float | None, kinds: bool = False) -> str:
    if not entries or tolerance is None:
        return "—" if not entries else f"{len(entries)} (no tolerance)"
    ok = sum(abs(e.relative_difference) <= tolerance for e in entries)
    text = f"{ok}/{len(entries)} ({100 * tolerance:g}%)"
    if kinds:
        counts = {k: sum(e.kind == k for e in entries) for k in KINDS}
        text += " " + ", ".join(f"{n} {k}" for k, n in counts.items() if n)
    return text


def release_compiled_programs() -> None:
    """Drop JAX's in-memory caches of traced and compiled programs between experiments.

    Each program XLA compiles for the CPU holds its own memory mappings; one process
    that runs every experiment (thousands of programs: co-designs, fronts, sweeps) ran
    out of them (LLVM "Unable to allocate section memory", the kernel's
    ``vm.max_map_count``). An experiment's programs are not reused by the next, and the
    persistent compilation cache keeps any recompilation cheap.
    """
    import jax  # noqa: PLC0415 (this module is otherwise free of JAX)

    jax.clear_caches()
    gc.collect()
