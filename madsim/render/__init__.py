"""Pictures of tracks and races; a door for people, never on the simulation's hot path.

- `trackmap`: track map PNGs (matplotlib).
- `raster`, `kernels`: the track as coloured quads and compiled rasters (numpy/numba).
- `image_obs`: egocentric top-down image observations (no pygame).
- `scene`, `topdown`: the pygame top-down view (`Renderer`), frames as arrays or a window.
- `envview`: `render_mode` ("human", "rgb_array") for the envs.
- `trace`, `video`, `plots`: serve traces, video files (MP4/GIF), run plots.

Nothing here is imported by `import madsim`; pygame is imported only by `topdown`.
"""
