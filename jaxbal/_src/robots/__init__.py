"""The robots of the four papers, one module each (plus their balancing helpers).

:data:`ROBOTS` maps the public constructor names (also the CLI's robot names) to the
constructors; :func:`by_name` resolves a name or an old alias.
"""

from __future__ import annotations

from jaxbal._src.robots.dual_v import dual_v
from jaxbal._src.robots.orthoglide import orthoglide
from jaxbal._src.robots.planar_arm import planar_2r, planar_3r
from jaxbal._src.robots.scara import scara

#: constructor name -> constructor of the nominal robot of its paper.
ROBOTS = {
    "planar_2r": planar_2r,
    "planar_3r": planar_3r,
    "scara": scara,
    "dual_v": dual_v,
    "orthoglide": orthoglide,
}
#: old spellings kept as aliases.
ALIASES = {"2r": "planar_2r", "3r": "planar_3r", "dual-v": "dual_v", "dualv": "dual_v"}


def by_name(name: str):
    """The nominal robot called ``name`` (a key of :data:`ROBOTS` or an alias).

    Raises:
        ValueError: an unknown name (the message lists the known ones).
    """
    key = ALIASES.get(name.strip().lower(), name.strip().lower())
    if key not in ROBOTS:
        raise ValueError(f"unknown robot {name!r}; choose one of {sorted(ROBOTS)}")
    return ROBOTS[key]()
