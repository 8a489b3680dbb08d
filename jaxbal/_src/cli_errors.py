"""How the ``jaxbal`` commands report an error: one line on stderr, ``error: …``, and
exit status 2, never a traceback; a file-system error as ``cannot write PATH:
REASON``; long NumPy arrays in a message (the instants of a move that fails)
shortened to their ends and count.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import NoReturn

import typer

__all__ = ["cannot_write", "fail", "shorten_arrays"]

#: a NumPy array's repr in a message, ``array([0.  , 0.005, …])`` over several lines.
_ARRAY = re.compile(r"array\(\[([^\[\]]*)\]\)")
#: arrays of more values than this are shortened.
SHORT = 6


def fail(message) -> NoReturn:
    """Print ``error: message`` on stderr and exit with status 2."""
    typer.echo(f"error: {message}", err=True)
    raise typer.Exit(code=2)


def cannot_write(path, error: OSError) -> str:
    """``cannot write PATH: REASON`` (naming the folder at fault when it is not PATH)."""
    reason = error.strerror or str(error)
    at = f" ({error.filename})" if error.filename and Path(error.filename) != Path(path) else ""
    return f"cannot write {path}: {reason}{at}"


def shorten_arrays(text: str) -> str:
    """``text`` with each NumPy array repr of more than :data:`SHORT` values written
    ``[first, second, …, last] (n values)`` on one line."""

    def short(match) -> str:
        values = [v.strip() for v in match.group(1).split(",") if v.strip()]
        if len(values) <= SHORT:
            return f"[{', '.join(values)}]"
        return f"[{values[0]}, {values[1]}, …, {values[-1]}] ({len(values)} values)"

    return _ARRAY.sub(short, text)
