"""Command-line pieces that the benchmark scripts share, importable without JAX or
jaxbal (``first_call.py`` parses its arguments before it times its imports): the robot
names and argument types that reject what would fail later, with a usage message.
``cases.MOVES`` has one move per name of :data:`ROBOTS`, in its order (a test checks it).
"""

from __future__ import annotations

import argparse

ROBOTS = ("planar_2r", "planar_3r", "scara", "dual_v", "orthoglide")


def command_line(prog: str, doc: str) -> argparse.ArgumentParser:
    """A script's parser: its name, and its module docstring as the description."""
    return argparse.ArgumentParser(
        prog=prog, description=doc, formatter_class=argparse.RawDescriptionHelpFormatter
    )


def _integer_at_least(least: int):
    """An ``argparse`` type: an integer ≥ ``least`` (``1_000_000`` is accepted)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
        if value < least:
            raise argparse.ArgumentTypeError(f"must be at least {least}, got {value}")
        return value

    parse.__name__ = f"integer >= {least}"  # argparse names the type in its errors
    return parse


#: ``argparse`` types: an integer ≥ 1, an integer ≥ 0
positive_int, count = _integer_at_least(1), _integer_at_least(0)


def positive_float(text: str) -> float:
    """An ``argparse`` type: a finite number > 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not 0.0 < value < float("inf"):
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {value}")
    return value
