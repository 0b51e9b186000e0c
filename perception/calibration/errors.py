"""The calibration family's one root exception."""

from ipbench.perception.cloud import PerceptionError

__all__ = ["CalibrationError"]


class CalibrationError(PerceptionError):
    """Bad calibration input or a calibration that cannot be computed; the message says which
    and how to fix it."""
