"""The stop module of the paper: relevancy-based early stopping (DESIGN 3.4)."""

from efficienteqa.stop.rules import RelevancyStopper, StopCheck, StopConfig, step_budget

__all__ = ["RelevancyStopper", "StopCheck", "StopConfig", "step_budget"]
