"""Communication buffer: one-step delay, FIFO contents and sizes (spec s. 9, paper)."""

from types import SimpleNamespace

import gymnasium
import numpy as np
import pytest

from madsim.agents.comms import CommBuffer, CommHub


def test_buffer_length_one_holds_the_last_message():
    buf = CommBuffer(1, 2)
    assert buf.request().tolist() == [0.0, 0.0]
    buf.push(np.array([1.0, 2.0]))
    buf.push(np.array([3.0, 4.0]))
    assert buf.request().tolist() == [3.0, 4.0]


def test_buffer_length_three_is_oldest_first_zero_padded_in_front():
    buf = CommBuffer(3, 2)
    buf.push(np.array([1.0, 2.0]))
    assert buf.request().tolist() == [0, 0, 0, 0, 1, 2]
    buf.push(np.array([3.0, 4.0]))
    assert buf.request().tolist() == [0, 0, 1, 2, 3, 4]
    buf.push(np.array([5.0, 6.0]))
    buf.push(np.array([7.0, 8.0]))
    assert buf.request().tolist() == [3, 4, 5, 6, 7, 8]
    buf.reset()
    assert buf.request().tolist() == [0] * 6 and buf.count == 0


def hub_two_agents(length_b=3):
    box2 = gymnasium.spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
    box3 = gymnasium.spaces.Box(np.array([-1, 0, 0], np.float32), np.array([1, 1, 1], np.float32))
    links = {"a": SimpleNamespace(senders=("b",), variables=("peerActions", "speedX"), buffer_length=1),
             "b": SimpleNamespace(senders=("a", "b"), variables=("action", "trackPos"),
                                  buffer_length=length_b)}
    return CommHub(links, {"a": box2, "b": box3})


def row(speed_kmh, track_pos):
    return {"speedX": speed_kmh, "trackPos": track_pos}


def test_sizes_and_bounds_for_buffer_lengths_one_and_three():
    hub = hub_two_agents()
    assert hub.size("a") == 1 * (3 + 1)                   # b's 3 actions + speedX
    assert hub.size("b") == 3 * ((2 + 1) + (3 + 1))        # a: 2 actions + trackPos; b: 3 + 1
    sb = hub.space("b")
    assert sb.shape == (21,)
    msg_low = [-1, -1, -np.inf, -1, 0, 0, -np.inf]
    assert sb.low.tolist() == msg_low * 3
    assert hub.vector("b").shape == (21,) and hub.size("nobody") == 0


def test_one_step_delay_and_contents():
    hub = hub_two_agents()
    hub.reset()
    assert not hub.vector("a").any() and not hub.vector("b").any()    # reset: zeros
    rows0 = {"a": row(50.0, 0.1), "b": row(100.0, -0.2)}               # seen before acting
    act1 = {"a": np.array([0.5, -0.5]), "b": np.array([0.1, 0.9, 0.0])}
    hub.send(rows0, act1)
    # a hears b: b's action of this step, b's speedX (km/h / 50) from before it acted
    assert hub.vector("a") == pytest.approx([0.1, 0.9, 0.0, 2.0])
    m1 = [0.5, -0.5, 0.1, 0.1, 0.9, 0.0, -0.2]
    assert hub.vector("b") == pytest.approx([0] * 14 + m1)
    rows1 = {"a": row(60.0, 0.3), "b": row(90.0, -0.1)}
    act2 = {"a": np.array([1.5, 0.0]), "b": np.array([0.0, 0.0, 1.0])}   # 1.5 outside the box
    hub.send(rows1, act2)
    m2 = [1.0, 0.0, 0.3, 0.0, 0.0, 1.0, -0.1]
    assert hub.vector("b") == pytest.approx([0] * 7 + m1 + m2)
    assert hub.space("b").contains(hub.vector("b"))


def test_a_sender_that_left_contributes_zeros():
    hub = hub_two_agents(length_b=1)
    hub.send({"b": row(100.0, -0.2)}, {"b": np.array([0.1, 0.9, 0.0])})
    assert hub.vector("b") == pytest.approx([0, 0, 0, 0.1, 0.9, 0.0, -0.2])


def test_unknown_sender_or_variable_is_refused():
    box = gymnasium.spaces.Box(-1.0, 1.0, shape=(2,))
    with pytest.raises(ValueError, match="unknown sender"):
        CommHub({"a": SimpleNamespace(senders=("z",), variables=("action",), buffer_length=1)}, {"a": box})
    with pytest.raises(ValueError, match="unknown communication variable"):
        CommHub({"a": SimpleNamespace(senders=("a",), variables=("speed",), buffer_length=1)}, {"a": box})
