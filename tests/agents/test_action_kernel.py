"""The compiled action mapping (madsim.agents.action_kernel) against numpy's own arithmetic."""

import numpy as np

from madsim.agents.action_kernel import begin_actions, clip_actions


def test_the_manual_gear_is_numpys_round_halves_to_even():
    # g at exact halves of the gear scale (non-normalised: the gear itself; normalised: the
    # (a + 1) * 3.5 - 1 map) and around them: np.round rounds 0.5 -> 0, 1.5 -> 2, 2.5 -> 2
    halves = np.array([-1.5, -0.5, 0.5, 1.5, 2.5, 3.5, 4.5, 5.5, 6.5])
    g = np.concatenate([halves, np.nextafter(halves, -np.inf), np.nextafter(halves, np.inf),
                        np.linspace(-1.0, 1.0, 101), (halves + 1.0) / 3.5 - 1.0])
    for normalised in (False, True):
        chosen = np.zeros((g.size, 3))
        chosen[:, 2] = g
        slots = np.arange(g.size, dtype=np.int64)
        gear = np.zeros(g.size)
        sab = np.zeros((g.size, 3))
        begin_actions(slots, chosen, False, normalised, True, False, -1.0, 1.0, np.zeros(0), sab,
                      gear, np.zeros(0), np.zeros(0))
        want = np.round(-1.0 + 3.5 * (g + 1.0) if normalised else g)
        assert np.array_equal(gear, want) and np.array_equal(np.signbit(gear), np.signbit(want))
    assert np.array_equal(np.round(halves), [-2.0, -0.0, 0.0, 2.0, 2.0, 4.0, 4.0, 6.0, 6.0])


def test_actions_are_clipped_as_numpy_clips_and_the_first_non_finite_one_is_named():
    low, high = np.array([-1.0, 0.0, 0.0]), np.array([1.0, 1.0, 1.0])
    a = np.array([[-2.0, 0.5, 1.5], [-0.0, np.inf, np.nan], [0.25, -1e300, 1.0]])
    out = np.empty_like(a)
    assert clip_actions(a, low, high, out) == 4            # row 1, column 1: the inf
    want = np.minimum(high, np.maximum(low, a))
    assert np.array_equal(out, want, equal_nan=True)
    assert clip_actions(want[[0, 2]], low, high, out[:2]) == -1
