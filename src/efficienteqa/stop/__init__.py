"""The stop module of the paper: relevancy-based early stopping (SPEC 3.4)."""

from efficienteqa.stop.relevancy import RelevancyStopper, StopCheck, StopConfig, step_budget

__all__ = ["RelevancyStopper", "StopCheck", "StopConfig", "step_budget"]
