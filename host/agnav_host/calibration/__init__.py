"""Calibration wizard: raw PWM sweeps -> measured steering angle / speed -> monotone tables ->
AGNAV_CALIB_TABLE write, read-back verification and EEPROM save (ref 003, section 6.5)."""

from .fit import CalibFitError, FitResult, fit_table, isotonic_increasing, steer_from_motion

__all__ = ["CalibFitError", "FitResult", "fit_table", "isotonic_increasing", "steer_from_motion"]
