"""Capability envelopes: how far each controller goes along each axis of difficulty (wbcbench.envelope.axes), by
bisection over normal runs (wbcbench.envelope.search), reported as a table and radar plots
(wbcbench.envelope.report)."""

from .axes import AXES, Axis, available_axes, get_axis, register_axis

__all__ = ["AXES", "Axis", "available_axes", "get_axis", "register_axis"]
