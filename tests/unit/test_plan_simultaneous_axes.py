"""configure() without axesToMove moves the block's simultaneousAxes that
the scan has (as pymalcolm): a line in x on an x/y motion controller."""

from __future__ import annotations

from malcolm.controllers.scan_steps import plan_scan
from malcolm.scan import gda


def test_simultaneous_axes_the_scan_lacks_are_left_out():
    line = gda.compound(gda.line("x", 5), duration=0.1)
    assert plan_scan("M", {"generator": line}, ["x", "y"]).steps_per_run == 5


def test_simultaneous_axes_choose_the_run_of_a_grid():
    grid = gda.compound(gda.line("y", 3), gda.line("x", 4), duration=0.1)
    assert plan_scan("M", {"generator": grid}, ["x"]).steps_per_run == 4
    assert plan_scan("M", {"generator": grid}, ["x", "y", "z"]).steps_per_run == 12
    # none of them in the scan: the whole scan, as with none given
    assert plan_scan("M", {"generator": grid}, ["z"]).steps_per_run == 12
