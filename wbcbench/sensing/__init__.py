"""Imperfect sensing between the simulator and the controller: noise, bias, drift, quantisation, delay, dropped
samples and a base estimator that really estimates (IMU orientation + leg kinematics), configured by a sensor
profile (`profiles/*.yaml`: `ideal`, the default, and `talos-like`), a scenario's `sensors:` section or
`--sensors PROFILE`.

    model = make_sensor_model("talos-like", robot, dt=1e-3, seed=0)
    meas = model.measure(sim.measure())    # what the controller sees this tick
"""

from .base_estimator import BaseEstimator
from .model import SensorModel, make_sensor_model
from .profile import SensorProfile, available_profiles, load_sensor_profile, parse_sensor_profile

__all__ = ["BaseEstimator", "SensorModel", "SensorProfile", "available_profiles", "load_sensor_profile",
           "make_sensor_model", "parse_sensor_profile"]
