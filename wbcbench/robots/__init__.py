"""Robots: pinocchio models built from example-robot-data, described by one profile YAML per robot."""

from .profile import (CollisionCheckSpec, FootSpec, GainSpec, RepulsionPointSpec, RepulsorSpec, RobotProfile, Side,
                      SoleSpec, available_robots, load_profile)
from .robot import Robot, load_robot

__all__ = ["CollisionCheckSpec", "FootSpec", "GainSpec", "RepulsionPointSpec", "RepulsorSpec", "Robot", "RobotProfile",
           "Side", "SoleSpec", "available_robots", "load_profile", "load_robot"]
