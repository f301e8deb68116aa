"""``habitat_sim.agent`` of the stand-in (see the package docstring)."""

from __future__ import annotations

import numpy as np


class AgentConfiguration:
    def __init__(self) -> None:
        self.height = 1.5
        self.radius = 0.1
        self.sensor_specifications: list = []


class AgentState:
    def __init__(self) -> None:
        self.position = np.zeros(3)
        self.rotation: object = [0.0, 0.0, 0.0, 1.0]


class Agent:
    def __init__(self, config: AgentConfiguration) -> None:
        self.config = config
        self.state = AgentState()

    def set_state(self, state: AgentState, reset_sensors: bool = True,
                  infer_sensor_states: bool = True, is_initial: bool = False) -> None:
        self.state = AgentState()
        self.state.position = np.array(state.position, dtype=float)
        self.state.rotation = list(np.asarray(state.rotation, dtype=float)) \
            if not hasattr(state.rotation, "w") else state.rotation

    def get_state(self) -> AgentState:
        return self.state
