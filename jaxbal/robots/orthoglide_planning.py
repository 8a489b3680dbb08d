"""The motion cases of Geng et al. (2021) for the Orthoglide."""

from jaxbal._src.robots.orthoglide import motion_cases, switching_times

__all__ = ["motion_cases", "switching_times"]
