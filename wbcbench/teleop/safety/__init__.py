"""Safety between the operator and the controller: the :class:`CommandFilter` (non-finite values, references inside
the body, jumps, speed and acceleration limits), the last stage of the teleoperation reference source."""

from . import command_filter as _command_filter
from .command_filter import *  # noqa: F403

__all__ = [*_command_filter.__all__]
