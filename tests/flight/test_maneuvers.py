"""Tests for aeromag_env.flight.maneuvers: the calibration box's manoeuvres found from the attitude
of simulated flights match the windows the simulator labelled, and the FOM on them matches the
FOM on the labels."""

from __future__ import annotations

import numpy as np
import pytest

from aeromag_env.compensation.compensate import _last_complete_box, compensate_scalar
from aeromag_env.compensation.metrics import figure_of_merit
from aeromag_env.compensation.real_metrics import FOM_NEEDS_LABELS, headline
from aeromag_env.compensation.tolles_lawson import TollesLawson
from aeromag_env.flight.data import Flight
from aeromag_env.flight.maneuvers import AXES, detect_maneuvers, last_box, maneuver_labels
from tests._flights import simulated


def _unlabelled(flight: Flight) -> Flight:
    return Flight({k: v for k, v in flight.fields.items() if k != "maneuver"}, dict(flight.attrs))


def test_every_labelled_window_is_found_with_its_axis_and_edges() -> None:
    f = simulated("nominal", 0)
    kinds = f.attrs["maneuver_kinds"].split(",")
    found = detect_maneuvers(f)
    labelled = f.maneuver_windows()
    assert len(found) == len(labelled) == 12
    for w, (mid, t0, t1) in zip(found, labelled, strict=True):
        assert w.axis == kinds[(mid - 1) % 3]
        # edges within 1 s of the labels: the envelope's half window plus a sample [s]
        assert abs(f.tt[w.start] - t0) < 1.0 and abs(f.tt[w.stop - 1] - t1) < 1.0
    box = last_box(found)
    assert box == found
    headings = [w.heading_deg for w in box[::3]]
    assert len({round(h / 90.0) % 4 for h in headings}) == 4  # four distinct headings


def test_a_survey_flight_has_no_box() -> None:
    f = simulated("nominal", 0, trajectory__pattern="survey", trajectory__duration_s=1200.0)
    assert last_box(detect_maneuvers(f)) is None
    assert detect_maneuvers(Flight({"tt": f.tt})) == []


def test_fom_on_detected_windows_matches_the_labelled_fom() -> None:
    f = simulated("nominal", 3)
    comp = compensate_scalar(f, "flux_a", "mag_1_uc", TollesLawson())
    labelled = figure_of_merit(comp.total_after, f.tt, f["maneuver"], f.sample_rate_hz)
    head = headline(_unlabelled(f), comp.total_before, comp.total_after, None)
    assert head["fom_source"] == "manoeuvres detected from the attitude"
    assert [w["axis"] for w in head["fom_windows"]] == list(AXES) * 4
    # windows up to 1 s wider than the labels add little to the peak-to-peaks: within 10 % [-]
    assert head["fom_nt"] == pytest.approx(labelled, rel=0.10)
    ids = maneuver_labels(f.n, last_box(detect_maneuvers(f)) or [])
    assert set(np.unique(ids)) == set(range(13))


def test_without_a_box_the_headline_says_fom_needs_one() -> None:
    f = simulated("nominal", 0, trajectory__pattern="survey", trajectory__duration_s=1200.0)
    mag = f["mag_1_uc"]
    head = headline(f, mag, mag - f["truth_interf_mag_1"], None)
    assert head["fom_nt"] is None and head["fom_note"] == FOM_NEEDS_LABELS


def test_a_corrupt_manoeuvre_id_does_not_stall_the_box_search() -> None:
    """A corrupted byte turned one label into 2**33 (found by hypothesis: the search walked every
    box up to it, 7e8 of them); the complete box is still found, at once."""
    f = simulated("nominal", 0)
    labels = f["maneuver"].copy()
    labels[np.flatnonzero(labels == 0)[-1]] = 2.0**33
    corrupt = Flight({**f.fields, "maneuver": labels}, dict(f.attrs))
    assert _last_complete_box(corrupt) == _last_complete_box(f) == 0
