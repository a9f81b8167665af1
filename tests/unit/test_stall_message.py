"""The frame timeout's message says what is known and suggests a cause only
where it is known (detector_manager.stall_message)."""

from types import SimpleNamespace

from malcolm.parts.detector_manager import stall_message

WALL = 1_700_000_000.0  # 22:13:20 UTC


def frames(first: int, count: int) -> SimpleNamespace:
    return SimpleNamespace(first=first, count=count, wall=WALL)


def test_external_acquiring_and_no_frame_made_means_triggers_not_arriving():
    text = stall_message("BL:DET", 2.5, frames(0, 4), "External", "Acquire", True)
    assert text == (
        "BL:DET: no frame 5 (uniqueId 5) within 2.5 s of frame 4, the last that"
        " came (22:13:20 UTC); trigger mode External; the driver is still"
        " acquiring (detectorState Acquire) and made 0 frames since: the"
        " External triggers are not arriving"
    )


def test_a_driver_that_stopped_means_the_detector_stopped():
    text = stall_message("BL:DET", 1, frames(0, 4), "External", "Idle", False, 0)
    assert text.endswith(
        "; trigger mode External; the driver is not acquiring (detectorState"
        " Idle) and made 0 frames since: the detector stopped before the run's"
        " frames were taken"
    )
    assert "triggers" not in text


def test_frames_made_that_do_not_arrive_are_not_blamed_on_triggers():
    for state, acquiring in (("Acquire", True), ("Idle", False)):
        text = stall_message(
            "BL:DET",
            1,
            frames(0, 4),
            "External",
            state,
            acquiring,
            made=12,
            counted_by="the writer",
            callbacks=False,
        )
        assert text.endswith(
            f"(detectorState {state}) and made 12 frames since: its frames do not"
            " reach the writer (the driver's arrayCallbacks is off)"
        ), text
        assert "triggers" not in text and "stopped" not in text
    text = stall_message("D", 1, frames(0, 4), "Internal", "Acquire", True, 2, "P")
    assert text.endswith("made 2 frames since: its frames do not reach P")


def test_internal_acquiring_and_no_frame_made_suggests_nothing():
    text = stall_message("BL:DET", 1, frames(7, 7), "Internal", "Acquire", True)
    assert text == (
        "BL:DET: no frame 8 (uniqueId 8) within 1 s of the run's start"
        " (22:13:20 UTC; no frame of this run came); trigger mode Internal;"
        " the driver is still acquiring (detectorState Acquire) and made 0"
        " frames since"
    )
