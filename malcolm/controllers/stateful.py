"""StatefulController: the plain stateful model (reset, disable)."""

from .base import Controller


class StatefulController(Controller):
    """Resetting, Ready, Fault, Disabling, Disabled; no scan logic."""

    model_name = "stateful"
