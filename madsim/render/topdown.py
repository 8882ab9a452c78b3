"""The pygame top-down view: track, cars as boxes of their real size, sensor overlays, a HUD.

`Renderer(track, size=(W, H), camera=...)` draws frames from plain arrays (`scene.CarPoses`,
`scene.Hud`, `scene.Overlay`) and returns them as (H, W, 3) uint8 arrays; `show()` puts the
last one in a window. Cameras: "track" (the whole track, fixed), "follow" (north up, centred
on a car), "rotate" (the car points up, 35 % from the bottom).

The static track is painted once per zoom level into 256 x 256 tiles (the compiled quad
filler of `madsim.raster.track_raster`, 2 x 2 supersampled, edges and barriers as anti-aliased
lines); a frame copies the tiles it needs (and, for "rotate", turns them with a compiled
bilinear sampler), then pygame draws the cars, ids, overlays and the HUD. Without a display
(no DISPLAY / WAYLAND_DISPLAY) SDL's dummy video driver is selected before pygame starts.
"""

from __future__ import annotations

import math
import os
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np

from madsim.raster import kernels
from madsim.raster.track_raster import BACKGROUND, FIXED_COLOURS, palette, track_quads
from madsim.render.scene import CAMERAS, CarPoses, Hud, Overlay, hud_lines
from madsim.tracks import Track

TILE_PX = 256
SUPERSAMPLE = 2
MAX_TILES = 96
KIND_COLOURS = {"learner": (232, 64, 48), "traffic": (48, 116, 232), "parked": (236, 172, 36)}
HIGHLIGHT_RGB = (255, 236, 64)
EDGE_RGB = (226, 226, 226)
BARRIER_RGB = (176, 48, 40)
RAY_RGB = (255, 220, 80)
SECTOR_RGB = (240, 80, 240)
HUD_BG = (22, 24, 28)
HUD_FG = (240, 240, 240)
HUD_FONT_PX = 20
ID_FONT_PX = 16
HUD_PAD = 6
MIN_CAR_PX = 8.0      # cars shorter than this on screen are drawn as dots of this diameter


def import_pygame():
    """pygame, with SDL's dummy video driver when there is no display; a clear error if
    pygame is missing."""
    os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    try:
        import pygame
    except ModuleNotFoundError:
        raise ModuleNotFoundError("the madsim renderer needs pygame: pip install 'madsim[render]' "
                                  "(or pip install pygame-ce)") from None
    if not pygame.font.get_init():
        pygame.font.init()
    return pygame


@dataclass(frozen=True)
class Camera:
    """mode: 'track', 'follow' or 'rotate'; ppm: zoom of the following cameras, pixels per
    metre (the track camera fits the track); car: row to follow (None: the highlighted car,
    else row 0)."""

    mode: str = "track"
    ppm: float = 6.0
    car: int | None = None

    def __post_init__(self):
        if self.mode not in CAMERAS:
            raise ValueError(f"camera mode must be one of {CAMERAS}, got {self.mode!r}")
        if not self.ppm > 0:
            raise ValueError(f"camera ppm must be > 0, got {self.ppm}")


class _View:
    """World -> screen: s = anchor + ppm * R(theta) (x - cx, -(y - cy)), screen y down;
    theta turns the picture counter-clockwise."""

    def __init__(self, cx, cy, ppm, theta, ax, ay):
        self.cx, self.cy, self.ppm, self.ax, self.ay = cx, cy, ppm, ax, ay
        self.cos, self.sin = math.cos(theta), math.sin(theta)
        self.theta = theta

    def to_screen(self, x, y):
        dx = (np.asarray(x) - self.cx) * self.ppm
        dy = -(np.asarray(y) - self.cy) * self.ppm
        return (self.ax + dx * self.cos + dy * self.sin,
                self.ay - dx * self.sin + dy * self.cos)


class Renderer:
    """Top-down frames of `track`; see the module docstring.

    size: (width, height) in pixels; camera: a Camera or its mode name; hud: draw the HUD
    when a Hud is given; ids: draw car ids.
    """

    def __init__(self, track: Track, *, size: tuple[int, int] = (800, 600),
                 camera: Camera | str = "track", ids: bool = True):
        self.pg = import_pygame()
        self.track = track
        self.size = (int(size[0]), int(size[1]))
        if self.size[0] < 16 or self.size[1] < 16:
            raise ValueError(f"size must be at least 16 x 16 pixels, got {size}")
        self.camera = camera if isinstance(camera, Camera) else Camera(mode=camera)
        self.draw_ids = ids
        self._quads = track_quads(track)
        self._palette = palette(track)
        self._lines = {"edge": [track.edge_polyline(s) for s in ("left", "right")],
                       "barrier": [track.barrier_polyline(s) for s in ("left", "right")]}
        self._pit_walls = track.pit_wall_quads()[0]     # (W, 4, 2) solid pit walls, m
        self._tiles: OrderedDict = OrderedDict()
        w, h = self.size
        self._rgb = np.zeros((h, w, 3), dtype=np.uint8)
        self._surface = self.pg.image.frombuffer(self._rgb, (w, h), "RGB")
        self._static_track = None
        self._canvas = None
        self._fonts = (self.pg.font.Font(None, HUD_FONT_PX), self.pg.font.Font(None, ID_FONT_PX))
        self._labels: dict[str, object] = {}
        self._window = None
        self._clock = None
        self.closed = False
        self.last_hud: list[str] = []
        self.hud_rect = None
        self.view: _View | None = None
        xmin, ymin, xmax, ymax = track.bounding_box
        margin = 0.04 * max(xmax - xmin, ymax - ymin) + 10.0
        self._fit_ppm = min(w / (xmax - xmin + 2 * margin), h / (ymax - ymin + 2 * margin))
        self._centre = ((xmin + xmax) / 2, (ymin + ymax) / 2)

    # --- static layer ---------------------------------------------------------------------

    def _tile(self, ppm: float, i: int, j: int) -> np.ndarray:
        """(TILE_PX, TILE_PX, 3) tile (i, j) of the track at zoom ppm: global pixel columns
        [i T, (i + 1) T) hold world x = column / ppm, rows [j T, (j + 1) T) world y = -row / ppm."""
        key = (ppm, i, j)
        tile = self._tiles.get(key)
        if tile is not None:
            self._tiles.move_to_end(key)
            return tile
        t = TILE_PX
        x0, y_top = i * t / ppm, -j * t / ppm
        quads = self._quads.window(x0 - 1, y_top - (t + 1) / ppm, x0 + (t + 1) / ppm, y_top + 1)
        tile = np.empty((t, t, 3), dtype=np.uint8)
        if quads.quads.shape[0] == 0:
            tile[:] = FIXED_COLOURS[BACKGROUND]
        else:
            labels = np.zeros((t * SUPERSAMPLE, t * SUPERSAMPLE), dtype=np.uint8)
            kernels.fill_quads(labels, quads.quads, quads.labels, x0, y_top, ppm * SUPERSAMPLE)
            kernels.downsample_rgb(labels, self._palette, SUPERSAMPLE, tile)
            self._draw_lines(tile, ppm, i * t, j * t)
        self._tiles[key] = tile
        while len(self._tiles) > MAX_TILES:
            self._tiles.popitem(last=False)
        return tile

    def _draw_lines(self, tile: np.ndarray, ppm: float, gx: int, gy: int) -> None:
        """Road edges (at zooms of 2 px/m and more) and barriers as anti-aliased lines; pit walls as
        filled quads."""
        pg = self.pg
        surf = pg.image.frombuffer(tile, (tile.shape[1], tile.shape[0]), "RGB")
        kinds = [("barrier", BARRIER_RGB, 2 if ppm >= 3.0 else 1)]
        if ppm >= 2.0:
            kinds.insert(0, ("edge", EDGE_RGB, 1))
        for name, rgb, width in kinds:
            for line in self._lines[name]:
                pts = np.stack([line[:, 0] * ppm - gx, -line[:, 1] * ppm - gy], axis=1)
                pts = np.vstack([pts, pts[:1]])
                for run in _runs_near(pts, tile.shape[1], tile.shape[0], 8.0):
                    if width == 1:
                        pg.draw.aalines(surf, rgb, False, run)
                    else:
                        pg.draw.lines(surf, rgb, False, run, width)
        if self._pit_walls.shape[0]:       # solid pit walls, filled in the barrier colour
            walls = self._pit_walls
            quads = np.stack([walls[..., 0] * ppm - gx, -walls[..., 1] * ppm - gy], axis=-1)
            h, w = tile.shape[:2]
            near = ((quads[..., 0].max(axis=1) >= -1.0) & (quads[..., 0].min(axis=1) <= w + 1.0)
                    & (quads[..., 1].max(axis=1) >= -1.0) & (quads[..., 1].min(axis=1) <= h + 1.0))
            for quad in quads[near]:
                pg.draw.polygon(surf, BARRIER_RGB, quad)

    def _compose(self, out: np.ndarray, ppm: float, ox: int, oy: int) -> None:
        """out (h, w, 3) = the static track at zoom ppm with out[0, 0] at global pixel (ox, oy)."""
        h, w = out.shape[:2]
        t = TILE_PX
        for j in range(oy // t, (oy + h - 1) // t + 1):
            for i in range(ox // t, (ox + w - 1) // t + 1):
                tile = self._tile(ppm, i, j)
                c0, r0 = max(ox, i * t), max(oy, j * t)
                c1, r1 = min(ox + w, (i + 1) * t), min(oy + h, (j + 1) * t)
                out[r0 - oy:r1 - oy, c0 - ox:c1 - ox] = tile[r0 - j * t:r1 - j * t, c0 - i * t:c1 - i * t]

    def _background(self, cars: CarPoses, follow: int) -> _View:
        """Paint the static track into the frame buffer; return the frame's view."""
        w, h = self.size
        cam = self.camera
        if cam.mode == "track":
            ppm = self._fit_ppm
            ox = round(self._centre[0] * ppm - w / 2)
            oy = round(-self._centre[1] * ppm - h / 2)
            if self._static_track is None:
                self._static_track = np.empty_like(self._rgb)
                self._compose(self._static_track, ppm, ox, oy)
            self._rgb[:] = self._static_track
            return _View((ox + w / 2) / ppm, -(oy + h / 2) / ppm, ppm, 0.0, w / 2, h / 2)
        ppm = cam.ppm
        cx, cy = float(cars.x[follow]), float(cars.y[follow])
        if cam.mode == "follow":
            ox = round(cx * ppm - w / 2)
            oy = round(-cy * ppm - h / 2)
            self._compose(self._rgb, ppm, ox, oy)
            return _View((ox + w / 2) / ppm, -(oy + h / 2) / ppm, ppm, 0.0, w / 2, h / 2)
        theta = math.pi / 2 - float(cars.yaw[follow])
        ax, ay = w / 2, 0.65 * h
        reach = math.hypot(max(ax, w - ax), max(ay, h - ay))
        side = 2 * math.ceil(reach) + 4
        ox = math.floor(cx * ppm) - side // 2
        oy = math.floor(-cy * ppm) - side // 2
        if self._canvas is None or self._canvas.shape[0] != side:
            self._canvas = np.empty((side, side, 3), dtype=np.uint8)
        canvas = self._canvas
        self._compose(canvas, ppm, ox, oy)
        kernels.rotate_into(self._rgb, canvas, cx * ppm - ox, -cy * ppm - oy, math.cos(theta),
                            math.sin(theta), ax, ay, np.array(FIXED_COLOURS[BACKGROUND], np.uint8))
        return _View(cx, cy, ppm, theta, ax, ay)

    # --- frames ---------------------------------------------------------------------------

    def frame(self, cars: CarPoses, ids=None, kinds=None, highlight: int | None = None, *,
              hud: Hud | None = None, overlay: Overlay | None = None) -> np.ndarray:
        """One frame (H, W, 3) uint8. cars: CarPoses (N cars); ids: N labels (default the row
        numbers); kinds: N of 'learner' / 'traffic' / 'parked' (default learner); highlight:
        row drawn with an outline, the one the overlay and the HUD belong to."""
        n = len(cars)
        ids = [str(i) for i in range(n)] if ids is None else [str(v) for v in ids]
        kinds = ["learner"] * n if kinds is None else list(kinds)
        if len(ids) != n or len(kinds) != n:
            raise ValueError(f"ids and kinds need one entry per car ({n}), got {len(ids)} and {len(kinds)}")
        for k in kinds:
            if k not in KIND_COLOURS:
                raise ValueError(f"car kind must be one of {tuple(KIND_COLOURS)}, got {k!r}")
        follow = self.camera.car if self.camera.car is not None else (highlight if highlight is not None else 0)
        if n and not 0 <= follow < n:
            raise IndexError(f"camera car {follow} out of range for {n} cars")
        view = self._background(cars, follow) if n or self.camera.mode == "track" else None
        if view is None:
            self._rgb[:] = FIXED_COLOURS[BACKGROUND]
        self.view = view
        if view is not None:
            if overlay is not None and highlight is not None:
                self._draw_overlay(view, cars, highlight, overlay)
            self._draw_cars(view, cars, ids, kinds, highlight)
            self._draw_scale(view)
        self._draw_hud(hud)
        return self._rgb.copy()

    def _draw_cars(self, view: _View, cars: CarPoses, ids, kinds, highlight) -> None:
        pg = self.pg
        surf = self._surface
        w, h = self.size
        c, s = np.cos(cars.yaw), np.sin(cars.yaw)
        hl, hw = cars.length / 2, cars.width / 2
        # body corners (front-left, front-right, rear-right, rear-left) and the windscreen
        corners = []
        for a, b in ((1.0, 1.0), (1.0, -1.0), (-1.0, -1.0), (-1.0, 1.0)):
            corners.append(view.to_screen(cars.x + a * hl * c - b * hw * s, cars.y + a * hl * s + b * hw * c))
        glass = []
        for a, b in ((0.55, 0.8), (0.55, -0.8), (0.2, -0.8), (0.2, 0.8)):
            glass.append(view.to_screen(cars.x + a * hl * c - b * hw * s, cars.y + a * hl * s + b * hw * c))
        order = [i for i in range(len(cars)) if i != highlight] + ([highlight] if highlight is not None else [])
        for i in order:
            poly = [(float(corners[k][0][i]), float(corners[k][1][i])) for k in range(4)]
            xs, ys = [p[0] for p in poly], [p[1] for p in poly]
            if max(xs) < -40 or min(xs) > w + 40 or max(ys) < -40 or min(ys) > h + 40:
                continue
            rgb = KIND_COLOURS[kinds[i]]
            if cars.length[i] * view.ppm < MIN_CAR_PX:    # too small to see: a dot marks it
                centre = (sum(xs) / 4, sum(ys) / 4)
                pg.draw.circle(surf, (20, 20, 20), centre, MIN_CAR_PX / 2 + 1)
                pg.draw.circle(surf, rgb, centre, MIN_CAR_PX / 2)
                if i == highlight:
                    pg.draw.circle(surf, HIGHLIGHT_RGB, centre, MIN_CAR_PX / 2 + 3, 2)
            else:
                pg.draw.polygon(surf, rgb, poly)
                pg.draw.aalines(surf, (20, 20, 20), True, poly)
                pg.draw.polygon(surf, (30, 34, 44),
                                [(float(glass[k][0][i]), float(glass[k][1][i])) for k in range(4)])
                if i == highlight:
                    pg.draw.lines(surf, HIGHLIGHT_RGB, True, poly, 2)
            if self.draw_ids:
                label = self._label(ids[i])
                cx, cy = sum(xs) / 4, min(ys)
                surf.blit(label, (int(cx - label.get_width() / 2), int(cy - label.get_height() - 2)))

    def _label(self, text: str):
        img = self._labels.get(text)
        if img is None:
            img = self._fonts[1].render(text, True, (255, 255, 255), (0, 0, 0))
            self._labels[text] = img
        return img

    def _draw_overlay(self, view: _View, cars: CarPoses, k: int, ov: Overlay) -> None:
        pg = self.pg
        surf = self._surface
        x, y, yaw = float(cars.x[k]), float(cars.y[k]), float(cars.yaw[k])
        origin = tuple(float(v) for v in view.to_screen(x, y))
        if ov.ray_angles_deg is not None and ov.ray_dist_m is not None:
            for a_deg, d in zip(ov.ray_angles_deg, ov.ray_dist_m):
                if d < 0:
                    continue
                h = yaw - math.radians(a_deg)
                end = view.to_screen(x + d * math.cos(h), y + d * math.sin(h))
                pg.draw.aaline(surf, RAY_RGB, origin, (float(end[0]), float(end[1])))
        if ov.sectors_m is not None:
            for j, d in enumerate(ov.sectors_m):
                if not 0 < d < 200.0:
                    continue
                b0, b1 = math.radians(-180.0 + 10.0 * j), math.radians(-170.0 + 10.0 * j)
                pts = [origin]
                for b in np.linspace(b0, b1, 4):
                    e = view.to_screen(x + d * math.cos(yaw - b), y + d * math.sin(yaw - b))
                    pts.append((float(e[0]), float(e[1])))
                pg.draw.polygon(surf, SECTOR_RGB, pts, 1)

    def _draw_scale(self, view: _View) -> None:
        """A scale bar in the bottom-left corner (10, 20, 50, 100, ... m)."""
        pg = self.pg
        h = self.size[1]
        target = 100.0 / view.ppm
        metres = next((m for m in (1, 2, 5, 10, 20, 50, 100, 200, 500, 1000, 2000) if m >= target), 5000)
        px = round(metres * view.ppm)
        y = h - 12
        pg.draw.line(self._surface, (255, 255, 255), (12, y), (12 + px, y), 3)
        for xe in (12, 12 + px):
            pg.draw.line(self._surface, (255, 255, 255), (xe, y - 5), (xe, y + 5), 2)
        self._surface.blit(self._label(f"{metres} m"), (16 + px, y - 8))

    def _draw_hud(self, hud: Hud | None) -> None:
        if hud is None:
            self.last_hud, self.hud_rect = [], None
            return
        lines = hud_lines(hud)
        images = [self.hud_text(line) for line in lines]
        width = max(img.get_width() for img in images) + 2 * HUD_PAD
        height = sum(img.get_height() for img in images) + 2 * HUD_PAD
        rect = self.pg.Rect(8, 8, width, height)
        self._surface.fill(HUD_BG, rect)
        y = rect.y + HUD_PAD
        for img in images:
            self._surface.blit(img, (rect.x + HUD_PAD, y))
            y += img.get_height()
        self.last_hud, self.hud_rect = lines, rect

    def hud_text(self, line: str):
        """The pygame surface of one HUD line, as the HUD draws it."""
        return self._fonts[0].render(line, True, HUD_FG, HUD_BG)

    # --- window ---------------------------------------------------------------------------

    def show(self, fps: float | None = None) -> bool:
        """Put the last frame in a window (opened on first use) and handle its events; with
        fps, wait so that calls come at most fps times a second. False once the user closed it."""
        pg = self.pg
        if self.closed:
            return False
        if self._window is None:
            pg.display.init()
            pg.display.set_caption(f"madsim - {self.track.name}")
            self._window = pg.display.set_mode(self.size)
            self._clock = pg.time.Clock()
        for event in pg.event.get():
            if event.type == pg.QUIT:
                self.close()
                return False
        self._window.blit(self._surface, (0, 0))
        pg.display.flip()
        if fps:
            self._clock.tick(fps)
        return True

    def close(self) -> None:
        """Close the window (if any) and drop the tile cache."""
        if self._window is not None:
            self.pg.display.quit()
            self._window = None
        self.closed = True
        self._tiles.clear()


def _runs_near(pts: np.ndarray, w: int, h: int, margin: float) -> list[np.ndarray]:
    """Consecutive stretches of a polyline (P, 2) that come within `margin` px of a w x h
    rectangle, each extended by one point on both ends so lines reach the border."""
    inside = ((pts[:, 0] > -margin) & (pts[:, 0] < w + margin)
              & (pts[:, 1] > -margin) & (pts[:, 1] < h + margin))
    if not inside.any():
        return []
    grow = inside.copy()
    grow[1:] |= inside[:-1]
    grow[:-1] |= inside[1:]
    idx = np.flatnonzero(grow)
    breaks = np.flatnonzero(np.diff(idx) > 1) + 1
    return [pts[r] for r in np.split(idx, breaks) if r.shape[0] >= 2]
