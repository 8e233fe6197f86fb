"""failure_injector: MAV_CMD_INJECT_FAILURE to the orchestrator's fault catalogue (PX4 SITL's
simulator role)."""

from firmware.modules.failure_injector.module import FailureInjectorModule

__all__ = ["FailureInjectorModule"]
