"""benchmarks/slide_window.py's yaw-rate estimate from SCR's `angle` (issue 12's sand2 round):
closed-form cases, including the heading wrapping through +-pi."""

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "slide_window.py"


@pytest.fixture(scope="module")
def slide():
    spec = importlib.util.spec_from_file_location("madsim_slide_window", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    yield mod
    sys.modules.pop("madsim_fidelity_bench", None)


def test_yaw_rate_of_a_car_following_a_turn_through_pi(slide):
    # the track turns left at 0.8 rad/s past heading pi (wrapped to -pi); the car points 0.1
    # rad right of it at first and swings by 0.05 sin(3 t): yaw = track - angle
    t = np.arange(0.0, 2.0, 0.0209)
    track = 2.9 + 0.8 * t
    angle = 0.1 + 0.05 * np.sin(3.0 * t)
    heading = (track + np.pi) % (2 * np.pi) - np.pi
    r = slide.yaw_rate(heading, angle, t)
    exact = 0.8 - 0.15 * np.cos(3.0 * t)
    # central differences: error (dt^2 / 6) x third derivative = 0.15 x 27 x 0.0209^2 / 6 inside
    assert np.max(np.abs(r[1:-1] - exact[1:-1])) < 4e-4
    assert np.max(np.abs(r - exact)) < 0.01           # one-sided at the two ends


def test_a_car_sliding_straight_on_has_the_turns_yaw_rate_minus_the_angle_growth(slide):
    # the car keeps its heading while the track turns under it: angle grows with the track
    t = np.linspace(0.0, 1.0, 49)
    track = 0.5 * t
    r = slide.yaw_rate(track, track - 0.2, t)
    assert np.allclose(r, 0.0, atol=1e-12)
