"""Inter-vehicle communication: what each learning car hears of the others (spec s. 9, paper).

A receiver lists its senders and the variables it hears from each: SCR fields (scaled as in
`madsim.agents.observations`) and `action` / `peerActions`, the sender's action. Messages
arrive with a delay of one step: the message a sender emits on step t holds the variables it
observed before acting on step t and the action it took on step t; the receiver finds it in its
observation of step t, i.e. the shared variables are from step t-1 and the actions are the
peers' previous actions as seen at the receiver's next decision. A FIFO keeps the last
`buffer_length` messages, oldest first, zeros until filled; its size is always
buffer_length * message width (MADRaS widened the space by one message only, spec 11 item 14).

Env side, once per env step:  hub.send(rows_before_acting, actions)  then
obs = concat(own_obs, hub.vector(receiver)); after reset the vectors are zeros.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import gymnasium
import numpy as np

from madsim.agents.observations import FIELD_BOUNDS, FIELD_SCALE, FIELD_WIDTH

__all__ = ["ACTION_VARIABLES", "COMM_VARIABLES", "CommBuffer", "CommHub"]

ACTION_VARIABLES = ("action", "peerActions")          # MADRaS devel's name, the paper's name
COMM_VARIABLES = ACTION_VARIABLES + tuple(FIELD_WIDTH)


class CommBuffer:
    """FIFO of the last `length` messages of `width` values each."""

    def __init__(self, length: int, width: int):
        if length < 1 or width < 0:
            raise ValueError(f"buffer length must be >= 1 and width >= 0, got {length}, {width}")
        self.length = int(length)
        self.width = int(width)
        self._data = np.zeros((self.length, self.width), dtype=np.float32)
        self.count = 0

    def reset(self) -> None:
        """Empty the buffer (all zeros)."""
        self._data[:] = 0.0
        self.count = 0

    def push(self, message: np.ndarray) -> None:
        """Append one message (width,), dropping the oldest when full."""
        self._data[:-1] = self._data[1:]
        self._data[-1] = message
        self.count = min(self.count + 1, self.length)

    def request(self) -> np.ndarray:
        """(length * width,) float32: the messages oldest first; slots never filled are zeros
        at the front, so the newest message is always the last block."""
        return self._data.reshape(-1).copy()


class CommHub:
    """Every receiver's buffer, filled from the senders' rows and actions each step.

    links: receiver name -> object with `senders`, `variables`, `buffer_length` (the config's
    CommConfig); action_spaces: agent name -> its action Box (the width and bounds of `action`).
    """

    def __init__(self, links: Mapping[str, object], action_spaces: Mapping[str, gymnasium.spaces.Box]):
        self.links = dict(links)
        self.action_spaces = dict(action_spaces)
        self.layouts: dict[str, list] = {}
        self.buffers: dict[str, CommBuffer] = {}
        self._spaces: dict[str, gymnasium.spaces.Box] = {}
        self._msg_bounds: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        for receiver, link in self.links.items():
            layout, low, high = [], [], []
            for sender in link.senders:
                if sender not in self.action_spaces:
                    raise ValueError(f"{receiver}: unknown sender {sender!r}")
                for var in link.variables:
                    lo, hi, width = self._bounds(sender, var)
                    layout.append((sender, var, width))
                    low.append(lo)
                    high.append(hi)
            low = np.concatenate(low) if low else np.zeros(0)
            high = np.concatenate(high) if high else np.zeros(0)
            self.layouts[receiver] = layout
            self.buffers[receiver] = CommBuffer(link.buffer_length, low.size)
            n = link.buffer_length
            self._spaces[receiver] = gymnasium.spaces.Box(
                np.tile(low, n).astype(np.float32), np.tile(high, n).astype(np.float32),
                dtype=np.float32)
            self._msg_bounds[receiver] = (low, high)

    def _bounds(self, sender: str, var: str):
        if var in ACTION_VARIABLES:
            space = self.action_spaces[sender]
            return (np.asarray(space.low, dtype=np.float64).ravel(),
                    np.asarray(space.high, dtype=np.float64).ravel(), space.shape[0])
        if var not in FIELD_WIDTH:
            raise ValueError(f"unknown communication variable {var!r}; one of {COMM_VARIABLES}")
        width = FIELD_WIDTH[var]
        lo, hi = FIELD_BOUNDS.get(var, (-np.inf, np.inf))
        return np.full(width, lo), np.full(width, hi), width

    def space(self, receiver: str) -> gymnasium.spaces.Box:
        """Box of the communication part of `receiver`'s observation."""
        return self._spaces[receiver]

    def size(self, receiver: str) -> int:
        """Length of that part: buffer_length * message width (0 for a non-receiver)."""
        return self._spaces[receiver].shape[0] if receiver in self._spaces else 0

    def reset(self) -> None:
        for buf in self.buffers.values():
            buf.reset()

    def message(self, receiver: str, rows: Mapping[str, Mapping],
                actions: Mapping[str, Sequence[float]]) -> np.ndarray:
        """The message `receiver` gets this step (width,): for each sender in order, each
        variable in order; zeros for a sender absent from rows/actions (it left the episode)."""
        parts = []
        for sender, var, width in self.layouts[receiver]:
            if var in ACTION_VARIABLES:
                value = actions.get(sender)
                scaled = None if value is None else np.asarray(value, dtype=np.float64).ravel()
            else:
                row = rows.get(sender)
                scaled = None if row is None else (
                    np.asarray(row[var], dtype=np.float64).ravel() * FIELD_SCALE.get(var, 1.0))
            parts.append(np.zeros(width) if scaled is None else scaled)
        msg = np.concatenate(parts) if parts else np.zeros(0)
        low, high = self._msg_bounds[receiver]
        return np.clip(msg, low, high).astype(np.float32)

    def send(self, rows: Mapping[str, Mapping], actions: Mapping[str, Sequence[float]]) -> None:
        """Push this step's message into every receiver's buffer. rows: each agent's row as
        it was before acting (the one it chose its action from); actions: the actions taken."""
        for receiver, buf in self.buffers.items():
            buf.push(self.message(receiver, rows, actions))

    def vector(self, receiver: str) -> np.ndarray:
        """The communication part of `receiver`'s observation, (size,) float32."""
        return self.buffers[receiver].request()
