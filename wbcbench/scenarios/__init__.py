"""Scenarios: YAML files dispatched on `kind:` to classes giving references and scenario metrics."""

from .base import (Scenario, ScenarioSpec, available_kinds, available_scenarios, load_scenario, make_scenario,
                   register_kind)

__all__ = ["Scenario", "ScenarioSpec", "available_kinds", "available_scenarios", "load_scenario", "make_scenario",
           "register_kind"]
