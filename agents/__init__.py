"""Policies for ``PneuNetGrasp-v0``: scripted pressure schedules (:mod:`agents.scripted`), and, with the
``rl`` extra, training and evaluation of learned ones.

Importing this package needs neither torch nor stable-baselines3.
"""

from agents.scripted import LinearRamp, StepPolicy

__all__ = ["LinearRamp", "StepPolicy"]
