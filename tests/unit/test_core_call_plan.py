"""A method's call plan (malcolm.core.callplan and Controller.call): the
same arguments and errors as MethodMeta.validate_args, and a meta changed
at run time used at once."""

from __future__ import annotations

import asyncio
import copy
from typing import Any

import pytest

from malcolm.controllers.base import Controller
from malcolm.core import (
    BadValueError,
    BooleanMeta,
    ChoiceMeta,
    MapMeta,
    MethodMeta,
    NumberMeta,
    Process,
    StringArrayMeta,
    StringMeta,
)
from malcolm.core.callplan import plan_args
from malcolm.parts import Part


def _meta() -> MethodMeta:
    return MethodMeta(
        MapMeta(
            {
                "exposure": NumberMeta("float64", display={"limitLow": 0.0,
                                                           "limitHigh": 10.0}),
                "frames": NumberMeta("uint32"),
                "axes": StringArrayMeta(),
                "name": StringMeta(),
                "mode": ChoiceMeta(["a", "b"]),
                "flag": BooleanMeta(),
                "nothing": StringMeta(),
                "odd": NumberMeta("int8"),
            },
            required=["exposure"],
        ),
        defaults={"frames": 1, "axes": ["x", "y"], "nothing": None, "odd": "zz"},
    )  # fmt: skip


CASES: list[Any] = [
    {},
    None,
    {"exposure": 1},
    {"exposure": 1.5, "name": "n", "mode": 1, "flag": "yes"},
    {"exposure": "0.1", "frames": None, "axes": ("a",)},
    {"exposure": 11.0},
    {"exposure": 1, "bogus": 2},
    {"exposure": "fast"},
    {"exposure": 1, "frames": -1},
    {"exposure": 1, "axes": "x"},
    {"exposure": 1, "axes": ["x", 2]},
    {"exposure": 1, "name": 5},
    {"exposure": 1, "mode": "c"},
    {"exposure": 1, "flag": 7},
    {"exposure": 1, "odd": 300},
    ["exposure"],
    "exposure",
]


def _outcome(func: Any, params: Any) -> Any:
    try:
        out = func(params)
    except BadValueError as e:
        return ("error", str(e))
    return ("ok", out, [type(v) for v in out.values()], list(out))


@pytest.mark.parametrize("params", CASES)
def test_the_plan_answers_as_validate_args(params: Any) -> None:
    meta = _meta()
    plan = plan_args(meta, "DET.configure")
    expected = _outcome(lambda p: meta.validate_args("DET.configure", p or {}), params)
    assert _outcome(lambda p: plan(meta, p), params) == expected


def test_a_default_that_is_not_a_scalar_is_a_copy_each_call() -> None:
    meta = MethodMeta(MapMeta({"d": MapMeta()}), defaults={"d": {"a": [1]}})
    plan = plan_args(meta, "m")
    first = plan(meta, {})
    assert first == {"d": {"a": [1]}}
    first["d"]["a"].append(2)
    assert plan(meta, {}) == {"d": {"a": [1]}}
    assert meta.defaults == {"d": {"a": [1]}}


@pytest.mark.parametrize(
    "change",
    [
        lambda m: setattr(m, "defaults", {"frames": 2}),
        lambda m: m.defaults.__setitem__("frames", 3),
        lambda m: m.defaults.pop("axes"),
        lambda m: m.defaults.__setitem__("axes", ["z"]),
        lambda m: setattr(m, "takes", MapMeta({"x": StringMeta()})),
        lambda m: m.takes.elements.__setitem__("x", StringMeta()),
        lambda m: m.takes.elements.pop("name"),
        lambda m: setattr(m.takes, "required", ()),
        lambda m: setattr(
            m.takes, "elements", {**m.takes.elements, "name": StringMeta()}
        ),
    ],
)
def test_a_plan_is_none_once_its_meta_changed(change: Any) -> None:
    meta = _meta()
    plan = plan_args(meta, "m")
    assert plan(meta, {"exposure": 1}) is not None
    change(meta)
    assert plan(meta, {"exposure": 1}) is None
    assert plan(copy.deepcopy(meta), {"exposure": 1}) is None  # another meta


class Greeter(Part):
    def setup(self, registrar: Any) -> None:
        self.method = registrar.add_method(self.greet)

    def greet(self, name: str, times: int = 1) -> dict[str, Any]:
        """Greet."""
        return {"greeting": f"hi {name}" * times}


def test_a_method_whose_meta_changes_at_run_time_uses_it_at_once() -> None:
    async def main() -> None:
        process = Process("test")
        part = Greeter("p")
        controller = Controller("G", [part])
        process.add_controller(controller)
        await process.start()
        method = part.method
        assert await process.post(["G", "greet"], {"name": "a"}) == {"greeting": "hi a"}
        assert method.args_plan is not None
        # a default given in place
        method.meta.defaults["times"] = 2
        assert await process.post(["G", "greet"], {"name": "a"}) == {
            "greeting": "hi ahi a"
        }
        assert process.get(["G", "greet", "took", "value"]) == {
            "name": "a",
            "times": 2,
        }
        # takes replaced: a new argument's type checked, an old one unknown
        method.meta.takes = MapMeta({"name": NumberMeta("int32")}, ["name"])
        with pytest.raises(BadValueError, match=r"^G.greet.name: expected a number"):
            await process.post(["G", "greet"], {"name": "a"})
        with pytest.raises(BadValueError, match=r"^G.greet.times: unknown argument"):
            await process.post(["G", "greet"], {"name": 1, "times": 1})
        # the whole meta replaced (as an Editor does)
        method.meta = MethodMeta(
            MapMeta({"name": StringMeta()}), defaults={"name": "z"}
        )
        assert await process.post(["G", "greet"], {}) == {"greeting": "hi z"}
        assert process.get(["G", "greet", "took", "value"]) == {"name": "z"}

    asyncio.run(main())


class Kinds(Part):
    """Methods of every kind of arguments and result."""

    def setup(self, registrar: Any) -> None:
        self.kept: list[Any] = []
        for func in (self.listed, self.plain, self.nothing, self.array, self.later):
            registrar.add_method(func)
        registrar.add_method(
            self.axes,
            meta=MethodMeta(
                MapMeta({"names": StringArrayMeta()}), defaults={"names": ["x"]}
            ),
        )

    def axes(self, names: Any) -> dict[str, Any]:
        """An array argument (its took is plain data)."""
        return {"n": len(names)}

    def listed(self, x: float = 1.0) -> dict[str, Any]:
        """A result that holds a list the method keeps."""
        self.kept = [1, 2]
        return {"items": self.kept}

    def plain(self, x: float = 1.0) -> dict[str, Any]:
        return {"y": x * 2}

    def nothing(self) -> list[int]:
        """A result that is not a mapping."""
        return [1, 2]

    def array(self) -> Any:
        import numpy

        return numpy.array([1.0, 2.0])

    async def later(self, x: float = 1.0) -> dict[str, Any]:
        await asyncio.sleep(0.001)
        return {"y": x}


def test_every_kind_of_call_publishes_its_logs_as_before() -> None:
    async def main() -> None:
        process = Process("test")
        part = Kinds("p")
        process.add_controller(Controller("K", [part]))
        await process.start()
        seen: list[Any] = []
        below: list[Any] = []
        process.subscribe(["K"], seen.append)
        process.subscribe(["K"], lambda c: None, below=below.append)
        seen.clear()
        block = process.get_block("K")
        for name, params, returned in [
            ("axes", {}, {"n": 1}),
            ("axes", {"names": ["a", "b"]}, {"n": 2}),
            ("listed", {}, {"items": [1, 2]}),
            ("plain", {"x": 2}, {"y": 4.0}),
            ("nothing", None, {}),
            ("array", {}, {}),
            ("later", {"x": 3}, {"y": 3.0}),
        ]:
            seen.clear()
            below.clear()
            await process.post(["K", name], params)
            method = block[name]
            assert method.returned.value == returned
            changes = [c for batch in seen for c in batch]
            assert changes == [
                [[name, "took"], method.took.to_dict()],
                [[name, "returned"], method.returned.to_dict()],
            ]
            assert len(seen) == (2 if name == "later" else 1)
            mine = [c for batch in below for c in batch]
            for (_path, data), (_, plain) in zip(mine, changes, strict=True):
                # a below subscriber: the log itself only when it is all scalars
                assert (data if isinstance(data, dict) else data.to_dict()) == plain
            assert process.get(["K", name, "took"]) == method.took.to_dict()
        part.kept.append(3)  # the method's list changes: not what was published
        assert [c for b in seen for c in b] != []
        assert block.listed.returned.to_dict()["value"] == {"items": [1, 2, 3]}

    asyncio.run(main())


def test_a_call_off_the_loop_is_refused_by_the_loop_guard() -> None:
    from malcolm.core import OffLoopError, enable_loop_guard
    from malcolm.core.threads import guard_trips

    async def main() -> None:
        process = Process("test")
        part = Kinds("p")
        controller = Controller("K", [part])
        process.add_controller(controller)
        await process.start()
        block = process.get_block("K")
        before = block.plain.took

        def elsewhere() -> None:
            asyncio.run(controller.call("plain", {"x": 1}))

        enable_loop_guard(True)
        with pytest.raises(OffLoopError, match=r"K\.plain"):
            await asyncio.get_running_loop().run_in_executor(None, elsewhere)
        assert block.plain.took is before
        guard_trips.clear()  # tripped on purpose

    asyncio.run(main())


def test_a_call_of_a_block_no_longer_hosted_publishes_nothing_when_it_ends() -> None:
    async def main() -> None:
        process = Process("test")
        old = Controller("K", [Kinds("p")])
        process.add_controller(old)
        await process.start()
        call = asyncio.ensure_future(process.post(["K", "later"], {"x": 2}))
        await asyncio.sleep(0)  # its took published; it waits
        process.remove_controller("K")
        new = Controller("K", [Kinds("p")])
        process.add_controller(new)
        await new.start()
        seen: list[Any] = []
        process.subscribe(["K"], seen.append)
        seen.clear()
        assert await call == {"y": 2.0}
        assert old.block.later.returned.value == {"y": 2.0}
        assert seen == []  # the new block's subscribers: not the old call's
        assert process.get(["K", "later", "returned", "value"]) == {}

    asyncio.run(main())
