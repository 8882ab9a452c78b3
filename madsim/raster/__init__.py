"""The rasteriser: tracks and cars painted into numpy arrays by compiled kernels.

Shared by what draws pictures for a learner (image observations, `madsim.agents.image_obs`)
and what draws them for people (`madsim.render`); it imports only tracks (and the SCR sensor
layout for `poses`), never agents, envs or render.

- `kernels`: the compiled pixel kernels (quad filling, egocentric sampling, rotation, poses).
- `track_raster`: the static track as coloured quads and label rasters.
- `poses`: car poses rebuilt from SCR sensors (distFromStart, trackPos, angle).
"""
