"""State machines as data: load and check the YAML models in ``models/``,
build ``transitions`` machines from them, and get phase decorators.

>>> from malcolm.fsm import RunnableDevice
>>> @RunnableDevice.Configure
... def configure(self, context): ...
>>> phases_of(configure)
('Configure',)
"""

from .check import check_model, resolve_controller
from .draw import to_dot, to_mermaid
from .errors import ModelError, Problem
from .loader import builtin_models_dir, clear_model_cache, load_model, model_names
from .model import AttributeRule, Model, PhaseInfo, StateInfo, Transition
from .phases import Phase, model_class, phases_of

Stateful = model_class(load_model("stateful"))
Manager = model_class(load_model("manager"))
RunnableDevice = model_class(load_model("runnable_device"))
AreaDetectorRunnableDevice = model_class(load_model("area_detector_runnable_device"))

__all__ = [
    "AreaDetectorRunnableDevice",
    "AttributeRule",
    "Manager",
    "Model",
    "ModelError",
    "Phase",
    "PhaseInfo",
    "Problem",
    "RunnableDevice",
    "StateInfo",
    "Stateful",
    "Transition",
    "builtin_models_dir",
    "check_model",
    "clear_model_cache",
    "load_model",
    "model_class",
    "model_names",
    "phases_of",
    "resolve_controller",
    "to_dot",
    "to_mermaid",
]
