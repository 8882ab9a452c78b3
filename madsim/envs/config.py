"""Scenario configuration: one YAML file -> frozen, validated dataclasses (madsim's one schema).

A scenario has MADRaS's three sections plus a curriculum (paper, Appendix A):

    server:                        # what every episode draws from
      tracks: [madsim-road]        # names, paths or "generated:<seed>[:<length_m>[:<width_m>]]"
      cars: [madsim-sedan]         # learning-car models offered (one drawn per agent)
      traffic_car: madsim-sedan    # default model of traffic cars
      traffic_count: [4, 5]        # traffic cars per episode (null: every traffic entry)
      order: fixed                 # fixed: episode k uses entry k mod n; random: uniform draws
      observation_noise: false     # SCR's multiplicative sensor noise
      max_steps: 20000             # ticks (0.02 s) before TimeOut; null: one lap at target speed
      track_limits: [-1.0, 1.0]    # allowed trackPos range (OutOfTrack, T-S lane mapping)
      distance_to_start: 25.0      # m of grid before the start line
      laps: 1                      # RaceOver distance, laps
      init_wait: 0                 # env steps with the "stop" action after reset (MADRaS devel)
    agents:                        # one entry per learning car
      - name: agent_0
        target_speed: 27.78        # m/s
        action: {space: TS, normalised: true}   # SAB (steer-accel-brake) or TS (trackPos-speed)
        pid: {accel_gains: [10.5, 0.05, 2.8], steer_gains: [5.1, 0.001, 1.0e-6], latency: 5}
        observation: {mode: SingleAgentInTrafficObs}
        rewards: {Progress2: {scale: 1.0}, AngularAcceleration: {scale: 5.0, max_ang_accl: 2.0}}
        dones: [RaceOver, TimeOut, Collision, TurnBackward, OutOfTrack]
        communication: {senders: [agent_1], variables: [peerActions], buffer_length: 1}
    traffic:                       # the first n entries drive when n traffic cars are drawn
      - {behaviour: DriveAndPark, target_speed: 13.89, parking_lane: [-0.8, 0.0],
         parking_distance: [185, 200]}
    curriculum: {unit: episodes, stages: [{start: 0, tracks: [madsim-road]}, {start: 500, ...}]}

Every key, its unit and default is a field of the dataclasses of `madsim.envs.schema`
(`server` is an `EpisodeConfig`). `load_config` (madsim.envs.loader) also reads MADRaS's own
files unchanged (master `madras_config.yml`, devel `sim_options_v2.yml` with its
`communications.yml`): `madsim.envs.madras_format` maps their keys onto these, misspellings
included; keys that only mean something to TORCS are accepted with a `ConfigWarning`.
Any fault raises `ConfigError` naming the file, the dotted key path (as written in the file),
the bad value and the nearest valid key.

This module is the public door: it re-exports the schema, the loader and the spaces.
"""

from madsim.envs import loader, schema, spaces
from madsim.envs.loader import *  # noqa: F403 (this module re-exports the layer's public names)
from madsim.envs.schema import *  # noqa: F403
from madsim.envs.spaces import *  # noqa: F403
from madsim.envs.validation import ConfigError, ConfigWarning

__all__ = sorted({*loader.__all__, *schema.__all__, *spaces.__all__, "ConfigError", "ConfigWarning"})
