"""What `MadrasEnv` and `MadrasParallelEnv` share in front of their `MadrasCore`: the core's
making, the curriculum's progress, the view (render modes 'human' and 'rgb_array') and close."""

from __future__ import annotations

from madsim.envs.core import CurriculumProgress, MadrasCore


class EnvFront(CurriculumProgress):
    """Mixin: `_open(...)` makes the core and the view (the class's `metadata` names the render
    modes); `_shown()` draws a 'human' window after a reset or step; `render()` and `close()`
    as gymnasium and PettingZoo expect."""

    def _open(self, config, backend, traffic_factory, render_mode: str | None,
              render_options: dict | None) -> None:
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise ValueError(f"render_mode must be None, 'human' or 'rgb_array', got {render_mode!r}")
        self.core = MadrasCore(config, backend=backend, traffic_factory=traffic_factory)
        self.config = self.core.config
        try:
            self._check_core()
        except Exception:
            self.core.close()
            raise
        self.render_mode = render_mode
        self._view = None
        if render_mode is not None:
            from madsim.render.envview import EnvView

            self._view = EnvView(render_mode, **(render_options or {}))
            self.metadata = {**self.metadata, "render_fps": EnvView.fps(self.core.ticks_per_step)}

    def _check_core(self) -> None:
        """Raise if this env cannot drive the core's scenario (before any window opens)."""

    def _shown(self) -> None:
        if self.render_mode == "human":
            self._view.render(self.core.view_state())

    def render(self):
        """'rgb_array': the current frame, (H, W, 3) uint8; 'human': draws the window, None."""
        return None if self._view is None else self._view.render(self.core.view_state())

    def close(self) -> None:
        if self._view is not None:
            self._view.close()
        self.core.close()
