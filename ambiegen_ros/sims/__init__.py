"""Executing scenarios and judging them with failure oracles (ROS-free).

* ``SurrogateExecutor``: the case study's fast surrogate plus a simple requirement oracle;
* ``full_model_executor``: the full-model simulators (``robot``, ``car``, ``room``) with the
  paper's oracles (collision, stall/loiter, timeout, out of lane, RMSE requirement).

Both return an ``Outcome``; sim nodes only call this package.
"""
from .full_model import full_model_executor
from .outcome import FAILURE_KINDS, Outcome
from .surrogate import SurrogateExecutor, execute

__all__ = ["FAILURE_KINDS", "Outcome", "SurrogateExecutor", "execute", "full_model_executor"]
