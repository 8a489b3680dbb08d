"""Command-line pieces that the benchmark scripts share, importable without JAX or
jaxbal (``first_call.py`` parses its arguments before it times its imports): the robot
names and argument types that reject what would fail later, with a usage message.
``cases.MOVES`` has one move per name of :data:`ROBOTS`, in its order (a test checks it).
"""

from __future__ import annotations

import argparse

ROBOTS = ("planar_2r", "planar_3r", "scara", "dual_v", "orthoglide")


def positive_int(text: str) -> int:
    """An ``argparse`` type: an integer ≥ 1 (``1_000_000`` is accepted)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def count(text: str) -> int:
    """An ``argparse`` type: an integer ≥ 0."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be at least 0, got {value}")
    return value


def positive_float(text: str) -> float:
    """An ``argparse`` type: a finite number > 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not 0.0 < value < float("inf"):
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {value}")
    return value
