"""Executing scenarios and judging them with failure oracles (ROS-free).

* ``SurrogateExecutor``: the case study's fast surrogate plus a simple requirement oracle;
* ``full_model_executor``: the full-model simulators (``robot``, ``car``, ``room``) with the
  paper's oracles (collision, stall/loiter, timeout, out of lane, RMSE requirement).

Both return an ``Outcome``; sim nodes only call this package. The names load on first use, so
that importing one light module of the package (``sims.options``) does not load the simulators.
"""
from __future__ import annotations

from importlib import import_module
from typing import Any

_HOMES = {"full_model_executor": ".full_model", "FAILURE_KINDS": ".outcome", "Outcome": ".outcome",
          "SurrogateExecutor": ".surrogate", "execute": ".surrogate"}


def __getattr__(name: str) -> Any:
    if name in _HOMES:
        return getattr(import_module(_HOMES[name], __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["FAILURE_KINDS", "Outcome", "SurrogateExecutor", "execute", "full_model_executor"]
