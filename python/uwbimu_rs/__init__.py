"""uwbimu_rs: UWB + IMU fusion filters for indoor positioning, implemented in Rust."""

from uwbimu_rs._native import ConfigError, NumericalError, UwbImuError

__all__ = ["ConfigError", "NumericalError", "UwbImuError"]
