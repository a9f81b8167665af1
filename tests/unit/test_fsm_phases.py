"""Phase decorators generated from the models."""

from __future__ import annotations

import asyncio
import inspect

import pytest

from malcolm.fsm import (
    AreaDetectorRunnableDevice,
    Manager,
    Phase,
    RunnableDevice,
    Stateful,
    load_model,
    model_class,
    phases_of,
)


def test_classes_are_named_after_their_models() -> None:
    for cls, stem in [
        (Stateful, "stateful"),
        (Manager, "manager"),
        (RunnableDevice, "runnable_device"),
        (AreaDetectorRunnableDevice, "area_detector_runnable_device"),
    ]:
        assert cls.__name__ == cls.model.name
        assert cls.model.path.stem == stem


def test_phase_objects() -> None:
    phase = RunnableDevice.Configure
    assert isinstance(phase, Phase)
    assert phase.name == "Configure"
    assert phase.model == "RunnableDevice"
    assert phase.description == RunnableDevice.model.phases["Configure"]
    assert phase == AreaDetectorRunnableDevice.Configure
    assert hash(phase) == hash(AreaDetectorRunnableDevice.Configure)
    assert phase != RunnableDevice.Validate
    assert Stateful.Reset == RunnableDevice.Reset
    assert [p.name for p in Stateful] == ["Init", "Reset", "Disable"]


def test_decorator_returns_the_function_and_records_the_phase() -> None:
    def configure(self, context):
        return 42

    decorated = RunnableDevice.Configure(configure)
    assert decorated is configure
    assert configure(None, None) == 42
    assert configure.__malcolm_phases__ == ("Configure",)
    assert phases_of(configure) == ("Configure",)


def test_decorators_stack_and_keep_async_functions() -> None:
    @RunnableDevice.Run
    @RunnableDevice.Seek
    async def move(self, context):
        return "moved"

    assert inspect.iscoroutinefunction(move)
    assert asyncio.run(move(None, None)) == "moved"
    assert phases_of(move) == ("Seek", "Run")


def test_phases_of_methods_and_undecorated() -> None:
    class Part:
        @AreaDetectorRunnableDevice.PreRunPluginStart
        def start(self, context): ...

        @staticmethod
        @Stateful.Init
        def make(): ...

        def other(self): ...

    assert phases_of(Part.start) == ("PreRunPluginStart",)
    assert phases_of(Part().start) == ("PreRunPluginStart",)
    assert phases_of(Part.make) == ("Init",)
    assert phases_of(Part.other) == ()


def test_unknown_phase_names_the_model_and_its_phases() -> None:
    with pytest.raises(AttributeError) as info:
        RunnableDevice.Configur  # noqa: B018
    message = str(info.value)
    assert "RunnableDevice has no phase 'Configur'" in message
    assert "Configure" in message and "PostRunReady" in message


def test_replaced_phase_is_gone() -> None:
    with pytest.raises(AttributeError, match="AreaDetectorRunnableDevice.*'Run'"):
        AreaDetectorRunnableDevice.Run  # noqa: B018
    assert AreaDetectorRunnableDevice.Running.name == "Running"
    assert AreaDetectorRunnableDevice.PreRunPluginStart.name == "PreRunPluginStart"
    assert AreaDetectorRunnableDevice.Configure == RunnableDevice.Configure
    assert RunnableDevice.Run.name == "Run"


def test_model_class_for_any_model() -> None:
    model = load_model("manager")
    cls = model_class(model)
    assert cls.__name__ == "Manager"
    assert cls.model is model
    assert cls.Save == Manager.Save
    with pytest.raises(AttributeError, match="Manager has no phase 'Configure'"):
        cls.Configure  # noqa: B018


def test_decorating_a_non_callable_is_an_error() -> None:
    with pytest.raises(TypeError, match="RunnableDevice.Configure"):
        RunnableDevice.Configure(42)
