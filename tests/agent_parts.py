"""What an MPC agent plans with, as tests read it: the residual its learner is fitted on and the
mesh it plans on (each resolved from the agent's settings on its current model)."""

from __future__ import annotations

from typing import Any


def residual_of(agent: Any) -> Any:
    """The residual an agent's learner is fitted on (its settings on its current model)."""
    return agent.config.residual.model(agent.model)


def mesh_of(agent: Any) -> Any:
    """The mesh an agent plans on."""
    return agent.config.schedule.mesh(agent.model.dt)
