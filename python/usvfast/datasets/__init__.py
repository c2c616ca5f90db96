"""Readers of public tracking data sets (real recordings with ground truth)."""

from usvfast.datasets.joyride import JoyrideRecording, load_joyride

__all__ = ["JoyrideRecording", "load_joyride"]
