"""Sensor profiles: the levels of noise, bias, drift, quantisation and delay of a robot's sensors, from YAML."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..config import Section, load_yaml
from ..errors import ConfigError, UnknownNameError

__all__ = ["SensorProfile", "available_profiles", "load_sensor_profile", "parse_sensor_profile"]

PROFILE_DIR = Path(__file__).parent / "profiles"


@dataclass(frozen=True)
class SensorProfile:
    """Sensor imperfections (SI units; stds of zero-mean Gaussian draws; 0 turns a term off).

    force_noise, torque_noise: white noise on each ankle F/T axis [N, N m]; force_bias, torque_bias: std of a
    constant offset drawn once per sensor axis; force_drift: random walk [N / sqrt(s)].
    gyro_noise, gyro_bias [rad/s], accel_noise, accel_bias [m/s^2]: the IMU's rate and acceleration;
    orientation_noise [rad]: roll/pitch noise of its orientation; yaw_drift [rad / sqrt(s)]: yaw random walk.
    encoder_resolution [rad]: joint positions quantised to this step (0: exact); encoder_offset [rad]: std of a
    constant calibration offset drawn once per joint (the zero of an absolute encoder set imprecisely).
    joint_velocity: "sensor" (the simulator's joint velocities) or "finite_difference" (of the encoder
    positions, low-passed at velocity_cutoff_hz).
    latency [s]: the measurement reaches the controller this much later (a multiple of the control period).
    drop_rate: probability that a tick's measurement is lost (the controller gets the previous one again).
    base: "ground_truth" (the simulator's base state) or "estimated" (`BaseEstimator`).
    """

    name: str = "ideal"
    force_noise: float = 0.0
    torque_noise: float = 0.0
    force_bias: float = 0.0
    torque_bias: float = 0.0
    force_drift: float = 0.0
    gyro_noise: float = 0.0
    gyro_bias: float = 0.0
    accel_noise: float = 0.0
    accel_bias: float = 0.0
    orientation_noise: float = 0.0
    yaw_drift: float = 0.0
    encoder_resolution: float = 0.0
    encoder_offset: float = 0.0
    joint_velocity: str = "sensor"
    velocity_cutoff_hz: float = 100.0
    latency: float = 0.0
    drop_rate: float = 0.0
    base: str = "ground_truth"
    file: str = ""

    @property
    def ideal(self) -> bool:
        """True when the measurement passes unchanged."""
        terms = (self.force_noise, self.torque_noise, self.force_bias, self.torque_bias, self.force_drift,
                 self.gyro_noise, self.gyro_bias, self.accel_noise, self.accel_bias, self.orientation_noise,
                 self.yaw_drift, self.encoder_resolution, self.encoder_offset, self.latency, self.drop_rate)
        return not any(terms) and self.joint_velocity == "sensor" and self.base == "ground_truth"


def parse_sensor_profile(sec: Section, name: str | None = None) -> SensorProfile:
    """A profile from a YAML mapping (a profile file, or a scenario's `sensors:` section)."""
    def group(key: str) -> Section:
        return sec.section(key, {})

    ft, imu, enc = group("force_torque"), group("imu"), group("encoders")
    nonneg = {"min": 0.0}
    p = SensorProfile(
        name=sec.str("name", name or "custom"),
        force_noise=ft.float("force_noise", 0.0, **nonneg), torque_noise=ft.float("torque_noise", 0.0, **nonneg),
        force_bias=ft.float("force_bias", 0.0, **nonneg), torque_bias=ft.float("torque_bias", 0.0, **nonneg),
        force_drift=ft.float("force_drift", 0.0, **nonneg),
        gyro_noise=imu.float("gyro_noise", 0.0, **nonneg), gyro_bias=imu.float("gyro_bias", 0.0, **nonneg),
        accel_noise=imu.float("accel_noise", 0.0, **nonneg), accel_bias=imu.float("accel_bias", 0.0, **nonneg),
        orientation_noise=imu.float("orientation_noise", 0.0, **nonneg),
        yaw_drift=imu.float("yaw_drift", 0.0, **nonneg),
        encoder_resolution=enc.float("resolution", 0.0, **nonneg),
        encoder_offset=enc.float("offset", 0.0, min=0.0, max=0.5),
        joint_velocity=sec.str("joint_velocity", "sensor", choices=["sensor", "finite_difference"]),
        velocity_cutoff_hz=sec.float("velocity_cutoff_hz", 100.0, positive=True),
        latency=sec.float("latency", 0.0, min=0.0, max=0.1),
        drop_rate=sec.float("drop_rate", 0.0, min=0.0, max=0.5),
        base=sec.str("base", "ground_truth", choices=["ground_truth", "estimated"]),
        file=sec.file or "")
    for s in (ft, imu, enc, sec):
        s.finish()
    return p


def available_profiles() -> list[str]:
    return sorted(p.stem for p in PROFILE_DIR.glob("*.yaml"))


def load_sensor_profile(name_or_path: str | Path, *, key: str = "--sensors") -> SensorProfile:
    """A shipped profile by name (`ideal`, `talos-like`) or a profile YAML file."""
    path = Path(name_or_path)
    if path.suffix not in (".yaml", ".yml"):
        names = available_profiles()
        if str(name_or_path) not in names:
            raise UnknownNameError("sensor profile", str(name_or_path), names, key=key)
        path = PROFILE_DIR / f"{name_or_path}.yaml"
    if not path.is_file():
        raise ConfigError(f"no such sensor profile file: {path}", key=key)
    return parse_sensor_profile(Section(load_yaml(path), str(path)), name=path.stem)
