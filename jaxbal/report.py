"""Result tables, atomic file output and the report of ``jaxbal reproduce`` (used by
the experiments)."""

from jaxbal._src.report import (
    Context,
    Entry,
    Experiment,
    Result,
    Table,
    atomic_write_bytes,
    atomic_write_text,
    release_compiled_programs,
    save_figure,
)
from jaxbal._src.studies import plot_histories

__all__ = [
    "Context",
    "Entry",
    "Experiment",
    "Result",
    "Table",
    "atomic_write_bytes",
    "atomic_write_text",
    "plot_histories",
    "release_compiled_programs",
    "save_figure",
]
