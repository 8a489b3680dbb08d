"""Placeholder: filled in by the scara work (see the issue). Not yet implemented."""


def scara(*args, **kwargs):
    raise NotImplementedError("jaxbal.robots.scara is not implemented yet")
