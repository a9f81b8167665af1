"""The web GUI in headless Chromium against the served demo."""

from __future__ import annotations

import json
import re

from playwright.sync_api import expect

from malcolm.demo import demo_generator


def open_block(page, mri: str) -> None:
    page.goto(f"{page.served.url}#/block/{mri}")
    expect(page.locator(f'[data-view="{mri}"] .badge')).to_have_text("Ready")


def test_block_list_and_a_put_both_ways(page):
    page.goto(page.served.url)
    for mri in ("HELLO", "COUNTER", "MOTOR:X", "SCAN"):
        expect(page.locator(f'#blocks li[data-mri="{mri}"] .state')).to_have_text(
            "Ready"
        )
    open_block(page, "COUNTER")
    counter = page.locator('[data-attr="counter"] input')
    counter.fill("5")
    counter.press("Enter")
    served = page.served
    expect(counter).to_have_value("5")
    _until(lambda: served.get(["COUNTER", "counter", "value"]) == 5)
    # a change made by someone else shows at once
    served.call(lambda: served.process.put(["COUNTER", "counter"], 42))
    expect(counter).to_have_value("42")
    # a refused put shows the error and changes nothing
    page.evaluate(
        "() => { const i = document.querySelector('[data-attr=delta] input');"
        " i.type = 'text'; i.value = 'lots'; i.dispatchEvent(new Event('change')); }"
    )
    expect(page.locator('[data-attr="delta"] .status')).to_contain_text("Error")
    assert served.get(["COUNTER", "delta", "value"]) == 1
    # an alarm shows next to its attribute
    from malcolm.core import Alarm

    block = served.call(lambda: served.process.get_block("COUNTER"))
    served.call(lambda: block.counter.set_value(7, alarm=Alarm.minor("rather high")))
    row = page.locator('[data-attr="counter"]')
    expect(row).to_have_attribute("data-severity", "minor")
    expect(row.locator(".alarm")).to_have_text("rather high")
    # the block list shows health as it changes
    health = page.locator('#blocks li[data-mri="HELLO"]')
    hello = served.call(lambda: served.process.get_block("HELLO"))
    served.call(lambda: hello.health.set_value("greeter: hoarse"))
    expect(health.locator(".health")).to_have_text("greeter: hoarse")
    expect(health).to_have_class(re.compile("unhealthy"))
    served.call(lambda: hello.health.set_value("OK"))
    expect(health).not_to_have_class(re.compile("unhealthy"))
    page.shots(page, "counter")


def test_the_block_list_shows_blocks_added_and_removed_while_open(page):
    from .test_web_protocol import _add_counter, _remove

    page.goto(page.served.url)
    late = page.locator('#blocks li[data-mri="LATE"]')
    expect(page.locator('#blocks li[data-mri="COUNTER"]')).to_have_count(1)
    expect(late).to_have_count(0)
    _add_counter(page.served, "LATE")
    expect(late.locator(".state")).to_have_text("Ready")
    late.locator("a").click()
    expect(page.locator('[data-view="LATE"] .badge')).to_have_text("Ready")
    _remove(page.served, "LATE")
    expect(late).to_have_count(0)
    expect(page.locator('#blocks li[data-mri="COUNTER"]')).to_have_count(1)


def test_method_result_and_error_are_shown(page):
    open_block(page, "HELLO")
    page.locator('[data-name="greet.name"]').fill("browser")
    page.locator('button[data-method="greet"]').click()
    expect(page.locator('[data-result="greet"]')).to_contain_text("Hello browser")
    page.locator('button[data-method="error"]').click()
    expect(page.locator('[data-result="error"]')).to_have_class(re.compile("error"))
    expect(page.locator('[data-result="error"]')).to_contain_text("Error")
    page.shots(page, "hello")


def test_scan_moves_the_progress_bar_and_the_state_diagram(page):
    open_block(page, "SCAN")
    run = page.locator('button[data-method="run"]')
    configure = page.locator('button[data-method="configure"]')
    expect(run).to_be_disabled()  # the model allows run in Armed only
    expect(configure).to_be_enabled()
    svg = page.locator("svg.fsm")
    expect(svg.locator('.state.current[data-state="Ready"]')).to_have_count(1)
    generator = demo_generator(ny=3, nx=4, duration=0.15)
    page.locator('[data-name="configure.generator"]').fill(json.dumps(generator))
    configure.click()
    expect(page.locator('[data-result="configure"]')).to_have_text("done")
    expect(svg).to_have_attribute("data-current", "Armed")
    expect(run).to_be_enabled()
    expect(configure).to_be_disabled()
    page.shots(page, "scan-armed")
    run.click()
    expect(svg).to_have_attribute("data-current", "Running")
    bar = page.locator('progress[data-progress="SCAN"]')
    expect(bar).not_to_have_attribute("data-done", "0")
    page.shots(page, "scan-running")
    expect(svg).to_have_attribute("data-current", "Finished", timeout=20000)
    expect(bar).to_have_attribute("data-done", "12")
    expect(bar).to_have_attribute("data-total", "12")
    trail = svg.get_attribute("data-trail").split(",")
    wanted = ["Ready", "Configuring", "Armed", "Running", "Finished"]
    assert [s for s in trail if s in wanted] == wanted, trail
    expect(run).to_be_disabled()
    page.shots(page, "scan-finished")


def _drag(page, locator, dx: float, dy: float) -> None:
    locator.wait_for()
    box = locator.bounding_box()
    x, y = box["x"] + 20, box["y"] + 10
    page.mouse.move(x, y)
    page.mouse.down()
    page.mouse.move(x + dx / 2, y + dy / 2, steps=4)
    page.mouse.move(x + dx, y + dy, steps=4)
    page.mouse.up()


def _layout(served, mri: str = "SCAN") -> dict[str, tuple[float, float, bool]]:
    t = served.get([mri, "layout", "value"])
    return {n: (x, y, v) for n, x, y, v in zip(t["name"], t["x"], t["y"], t["visible"])}


def _until(check, timeout: float = 10) -> None:
    import time

    end = time.monotonic() + timeout
    while not check():
        assert time.monotonic() < end, "not reached in time"
        time.sleep(0.05)


def test_drag_a_child_and_the_layout_table_changes(page):
    served = page.served
    open_block(page, "SCAN")
    palette = page.locator('[data-palette="SCAN"]')
    # all four start at (0, 0): the top one is the last drawn
    for name, (dx, dy) in [("y", (270, 130)), ("x", (140, 130)), ("DET2", (140, 0))]:
        _drag(page, palette.locator(f'[data-child="{name}"]'), dx, dy)
        _until(lambda n=name, d=(dx, dy): _layout(served)[n][:2] == d)
    expect(page.locator('[data-name="layout.2.x"]')).to_have_value("140")
    expect(page.locator('[data-name="layout.2.y"]')).to_have_value("130")
    expect(page.locator('[data-attr="modified"] .led')).to_have_class(re.compile("on"))
    assert served.get(["SCAN", "state", "value"]) == "Ready"
    page.shots(page, "palette")
    # hiding a child calls set_visible: its box goes
    page.locator('input[data-visible="DET2"]').uncheck()
    _until(lambda: _layout(served)["DET2"][2] is False)
    expect(palette.locator('[data-child="DET2"]')).to_have_count(0)


def test_save_a_design_and_load_it_back(page):
    served = page.served
    open_block(page, "SCAN")
    palette = page.locator('[data-palette="SCAN"]')
    _drag(page, palette.locator('[data-child="y"]'), 200, 100)
    _until(lambda: _layout(served)["y"][:2] == (200, 100))
    page.locator('[data-name="save.design"]').fill("browser")
    page.locator('button[data-method="save"]').click()
    expect(page.locator('[data-result="save"]')).to_have_text("done")
    expect(page.locator('[data-attr="design"] select')).to_have_value("browser")
    expect(page.locator('[data-attr="modified"] .led')).not_to_have_class(
        re.compile("on")
    )
    _drag(page, palette.locator('[data-child="y"]'), 100, -50)
    _until(lambda: _layout(served)["y"][:2] == (300, 50))
    expect(page.locator('[data-attr="modified"] .led')).to_have_class(re.compile("on"))
    page.locator('[data-name="load.design"]').fill("browser")
    page.locator('button[data-method="load"]').click()
    expect(page.locator('[data-result="load"]')).to_have_text("done")
    _until(lambda: _layout(served)["y"][:2] == (200, 100))
    expect(palette.locator('[data-child="y"]')).to_have_css("left", "220px")
    expect(page.locator('[data-attr="modified"] .led')).not_to_have_class(
        re.compile("on")
    )
    page.shots(page, "design-loaded")


def test_wiring_between_children_is_drawn_as_arrows(browser, tmp_path):
    from .conftest import Served, Shots
    from .wired import wired_process

    served = Served(wired_process)
    context = browser.new_context(viewport={"width": 1400, "height": 900})
    try:
        pg = context.new_page()
        pg.served = served
        open_block(pg, "BOX")
        palette = pg.locator('[data-palette="BOX"]')
        for name, (dx, dy) in [("PCAP", (330, 120)), ("PULSE", (200, 60))]:
            _drag(pg, palette.locator(f'[data-child="{name}"]'), dx, dy)
            _until(lambda n=name, d=(dx, dy): _layout(served, "BOX")[n][:2] == d)
        wires = palette.locator("path[data-wire]")
        expect(wires).to_have_count(0)  # every input is ZERO
        served.call(lambda: served.process.put(["BOX:PCAP", "INP"], "PULSE.OUT"))
        served.call(lambda: served.process.put(["BOX:PULSE", "INP"], "GATE.OUT"))
        expect(wires).to_have_count(2)
        expect(palette.locator('path[data-wire="PULSE.OUT → PCAP.INP"]')).to_have_count(
            1
        )
        expect(palette.locator('path[data-wire="GATE.OUT → PULSE.INP"]')).to_have_count(
            1
        )
        Shots(tmp_path)(pg, "wiring")
        # a hidden child's wires go with it
        pg.locator('input[data-visible="GATE"]').uncheck()
        _until(lambda: _layout(served, "BOX")["GATE"][2] is False)
        expect(wires).to_have_count(1)
    finally:
        context.close()
        served.close()


def test_the_exports_table_is_edited_in_place(page):
    served = page.served
    open_block(page, "SCAN")
    exports = page.locator('[data-attr="exports"]')
    exports.get_by_role("button", name="+ row").click()
    exports.locator('[data-name="exports.0.name"]').fill("frames")
    exports.locator('[data-name="exports.0.source"]').fill("DET1.framesTaken")
    exports.locator('[data-name="exports.0.description"]').fill("DET1's frames")
    exports.locator('[data-name="exports.put"]').click()
    _until(lambda: served.get(["SCAN", "exports", "value"])["name"] == ["frames"])
    # the manager takes its new parts through Disabled: reset brings it back
    expect(page.locator('button[data-method="reset"]')).to_be_enabled()
    page.locator('button[data-method="reset"]').click()
    expect(page.locator('[data-view="SCAN"] .badge')).to_have_text("Ready")
    expect(page.locator('[data-attr="frames"]')).to_have_count(1)
    assert "frames" in served.get(["SCAN", "meta", "fields"])
    # a bad row is refused with the reason, and the table is as it was
    exports.get_by_role("button", name="+ row").click()
    exports.locator('[data-name="exports.1.name"]').fill("nope")
    exports.locator('[data-name="exports.1.source"]').fill("NOPE.x")
    exports.locator('[data-name="exports.put"]').click()
    expect(exports.locator(".status")).to_contain_text("NOPE")
    assert served.get(["SCAN", "exports", "value"])["name"] == ["frames"]


def test_the_fixed_table_is_edited_in_place(page):
    """The manager's fixed table: a row added in the GUI is put, the manager
    goes through Disabled, reset writes the value to the child, and
    ``modified`` lights; a bad row is refused with its name."""
    served = page.served
    open_block(page, "SCAN")
    fixed = page.locator('[data-attr="fixed"]')
    expect(fixed.locator("th")).to_have_text(["name", "value"])
    fixed.get_by_role("button", name="+ row").click()
    fixed.locator('[data-name="fixed.0.name"]').fill("x.velocity")
    fixed.locator('[data-name="fixed.0.value"]').fill("50.0")
    fixed.locator('[data-name="fixed.put"]').click()
    _until(lambda: served.get(["SCAN", "fixed", "value"])["name"] == ["x.velocity"])
    assert served.get(["SCAN", "fixed", "value"])["value"] == ["50.0"]
    page.locator('button[data-method="reset"]').click()
    expect(page.locator('[data-view="SCAN"] .badge')).to_have_text("Ready")
    _until(lambda: served.get(["MOTOR:X", "velocity", "value"]) == 50.0)
    expect(page.locator('[data-attr="modified"] .led')).to_have_class(re.compile("on"))
    assert served.get(["SCAN", "modified", "value"]) is True
    # the row is held: another hand's change faults the manager, naming it
    served.call(lambda: served.process.put(["MOTOR:X", "velocity"], 7.0))
    expect(page.locator('[data-view="SCAN"] .badge')).to_have_text("Fault")
    expect(page.locator('[data-view="SCAN"] .health')).to_contain_text("x.velocity")
    page.locator('button[data-method="reset"]').click()
    expect(page.locator('[data-view="SCAN"] .badge')).to_have_text("Ready")
    _until(lambda: served.get(["MOTOR:X", "velocity", "value"]) == 50.0)
    # a bad row is refused with the reason, and the table is as it was
    fixed.get_by_role("button", name="+ row").click()
    fixed.locator('[data-name="fixed.1.name"]').fill("NOPE.velocity")
    fixed.locator('[data-name="fixed.1.value"]').fill("1")
    fixed.locator('[data-name="fixed.put"]').click()
    expect(fixed.locator(".status")).to_contain_text("NOPE.velocity")
    assert served.get(["SCAN", "fixed", "value"])["name"] == ["x.velocity"]
    page.shots(page, "fixed")


def test_the_gui_connects_again_when_the_server_is_back(page):
    from malcolm.io.web import start_web_server

    served = page.served
    open_block(page, "COUNTER")
    counter = page.locator('[data-attr="counter"] input')
    connection = page.locator("#connection")
    expect(connection).to_have_text("connected")
    port = served.server.port
    served.call(served.server.close)
    expect(connection).to_have_text("disconnected")
    served.call(lambda: served.process.put(["COUNTER", "counter"], 8))
    served.server = served.call(
        lambda: start_web_server(served.process, port, "127.0.0.1")
    )
    expect(connection).to_have_text("connected", timeout=10000)
    expect(counter).to_have_value("8")  # the subscription was made again
    served.call(lambda: served.process.put(["COUNTER", "counter"], 9))
    expect(counter).to_have_value("9")
    page.locator('button[data-method="increment"]').click()
    expect(counter).to_have_value("10")


def test_a_zebra2_managers_wiring_table_is_drawn(browser, tmp_path):
    from malcolm.parts.zebra2_demo import start_demo_zebra2

    from .conftest import Served, Shots

    served = Served(extras=start_demo_zebra2)
    context = browser.new_context(viewport={"width": 1400, "height": 900})
    try:
        pg = context.new_page()
        pg.served = served
        open_block(pg, "ZEBRA2")
        palette = pg.locator('[data-palette="ZEBRA2"]')
        # the box's 19 blocks start at (0, 0): place two of them apart
        for name, x, y in [("CLOCK1", 20, 120), ("PCAP", 300, 60)]:
            served.call(
                lambda n=name, x=x, y=y: served.process.post(
                    ["ZEBRA2", "set_position"], {"block_name": n, "x": x, "y": y}
                )
            )
        expect(palette.locator('[data-child="PCAP"]')).to_have_css("left", "320px")
        served.call(lambda: served.process.put(["ZEBRA2:PCAP", "TRIG"], "CLOCK1.OUT"))
        wire = palette.locator('path[data-wire="CLOCK1.OUT → PCAP.TRIG"]')
        expect(wire).to_have_count(1, timeout=15000)
        Shots(tmp_path)(pg, "zebra2-wiring")
        served.call(lambda: served.process.put(["ZEBRA2:PCAP", "TRIG"], "ZERO"))
        expect(wire).to_have_count(0, timeout=15000)
    finally:
        context.close()
        served.close()
