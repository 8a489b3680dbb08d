"""Placeholder: filled in by the dual_v work (see the issue). Not yet implemented."""


def dual_v(*args, **kwargs):
    raise NotImplementedError("jaxbal.robots.dual_v is not implemented yet")
