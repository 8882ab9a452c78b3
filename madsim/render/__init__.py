"""Pictures of tracks and races; a door for people, never on the simulation's hot path.

- `trackmap`: track map PNGs (matplotlib).
- `scene`, `topdown`: the pygame top-down view (`Renderer`), frames as arrays or a window.
- `envview`: `render_mode` ("human", "rgb_array") for the envs.
- `trace`, `video`, `plots`, `learning_curves`: serve traces, video files (MP4/GIF), run
  plots, a training run's learning curves.

The track rasters and pixel kernels are `madsim.raster` (shared with the image observations,
`madsim.agents.image_obs`). render draws what it is handed: it imports neither envs, agents
nor train (tests/render/test_import_rule.py). Nothing here is imported by `import madsim`;
pygame is imported only by `topdown`.
"""
