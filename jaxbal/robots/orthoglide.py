"""Placeholder: filled in by the orthoglide work (see the issue). Not yet implemented."""


def orthoglide(*args, **kwargs):
    raise NotImplementedError("jaxbal.robots.orthoglide is not implemented yet")
