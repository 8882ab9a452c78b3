"""`madsim train` with stable-baselines3: a short PPO run, its folder, reloading the policy."""

import csv
import json
import zipfile

import numpy as np
import pytest

pytest.importorskip("stable_baselines3", reason="stable-baselines3 not installed: pip install 'madsim[train]'")

from madsim.envs.config import load_config
from madsim.cli import main as cli_main
from madsim.train.evaluate import evaluate_policy
from madsim.train.sb3 import TrainError, TrainSettings, load_policy, train

# One T-S car on madsim-road, episodes of at most 1,500 ticks (300 steps) to keep it short.
TS = {
    "server": {"tracks": ["madsim-road"], "cars": ["madsim-sedan"], "max_steps": 1500},
    "agents": [{"name": "driver", "target_speed": 27.78, "action": {"space": "TS", "normalised": True},
                "pid": {"latency": 5}, "observation": {"mode": "SingleAgentSimpleLapObs"},
                "rewards": {"Progress2": {"scale": 1.0}, "Collision": {"scale": 10.0}},
                "dones": ["LapCompleted", "TimeOut", "Collision", "TurnBackward", "OutOfTrack"]}],
}
SMOKE = TrainSettings(steps=2048, num_envs=2, n_steps=256, batch_size=128, n_epochs=2,
                      eval_every=1024, eval_episodes=1, progress=False, verbose=False,
                      native_vec=False)


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("run")
    record = train(TS, out, SMOKE)
    return out, record


def _rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_run_folder_holds_policy_logs_checkpoints_and_config(run):
    out, record = run
    assert record["timesteps"] == 2048
    assert json.loads((out / "run.json").read_text())["timesteps"] == 2048
    assert load_config(out / "config.yml") == load_config(TS)          # the echoed config
    evals = _rows(out / "eval.csv")
    assert [int(r["timesteps"]) for r in evals] == [0, 1024, 2048]
    for r in evals:
        assert 0.0 <= float(r["lap_fraction"]) <= 1.0
        assert 0.0 <= float(r["completion_rate"]) <= 1.0
    progress = _rows(out / "progress.csv")
    assert max(int(float(r["time/total_timesteps"])) for r in progress) == 2048
    assert any(r.get("rollout/ep_rew_mean") for r in progress)         # episodes ended and counted
    names = sorted(p.name for p in (out / "checkpoints").iterdir())
    assert names == ["step_000000000.zip", "step_000001024.zip", "step_000002048.zip"]
    assert (out / "policy.zip").is_file() and (out / "best_policy.zip").is_file()


def test_reloaded_policy_repeats_the_final_evaluation(run):
    """The last row of eval.csv was measured with the in-memory model at step 2,048; the policy
    reloaded from policy.zip drives the same seeded episode to the same figures."""
    out, _ = run
    last = _rows(out / "eval.csv")[-1]
    policy = load_policy(out / "policy.zip")
    summary, _ = evaluate_policy(policy, TS, episodes=1)
    assert summary["mean_return"] == pytest.approx(float(last["mean_return"]), rel=1e-12)
    assert summary["lap_fraction"] == pytest.approx(float(last["lap_fraction"]), rel=1e-12)
    assert summary["mean_steps"] == float(last["mean_steps"])


def test_reloaded_policy_gives_the_saved_actions(run):
    """policy.zip and the step-2,048 checkpoint hold the same network: equal actions on a batch
    of observations; the untrained step-0 checkpoint acts differently (so the check can fail)."""
    out, _ = run
    policy = load_policy(out)                                  # the folder: DIR/policy.zip
    obs = np.random.default_rng(0).uniform(-1, 1, size=(64,) + policy.observation_space.shape)
    obs = obs.astype(np.float32)
    final = load_policy(out / "checkpoints" / "step_000002048.zip")
    untrained = load_policy(out / "checkpoints" / "step_000000000.zip")
    np.testing.assert_array_equal(policy(obs), final(obs))
    assert not np.array_equal(policy(obs), untrained(obs))
    one = policy(obs[0])                       # one observation: a batch of one, same network
    assert one.shape == policy.action_space.shape
    np.testing.assert_allclose(one, policy(obs)[0], atol=1e-6)   # float32 matmul order only
    assert policy.action_space.contains(one.astype(np.float32))


def test_an_occupied_run_folder_is_refused(run):
    out, _ = run
    with pytest.raises(TrainError, match="already holds a training run"):
        train(TS, out, SMOKE)


def test_bad_settings_and_multi_agent_configs_are_refused(tmp_path):
    with pytest.raises(TrainError, match="steps"):
        TrainSettings(steps=0)
    with pytest.raises(TrainError, match="algo"):
        TrainSettings(steps=10, algo="dqn")
    two = dict(TS, agents=[dict(TS["agents"][0], name="a"), dict(TS["agents"][0], name="b")])
    with pytest.raises(TrainError, match="2 .a, b."):
        train(two, tmp_path / "x", SMOKE)


def test_load_policy_errors_name_the_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="no policy file"):
        load_policy(tmp_path / "nothing.zip")
    bad = tmp_path / "policy.zip"
    bad.write_bytes(b"not a zip")
    with pytest.raises(TrainError, match="policy.zip: not a policy saved by madsim train"):
        load_policy(bad)
    other = tmp_path / "other.zip"                              # a zip, but of something else
    with zipfile.ZipFile(other, "w") as z:
        z.writestr("notes.txt", "hello")
    with pytest.raises(TrainError, match="other.zip: not a policy saved by madsim train"):
        load_policy(other)


def test_cli_reports_a_bad_config_in_one_line(tmp_path, capsys):
    cfg = tmp_path / "bad.yml"
    cfg.write_text("server: {trakcs: [madsim-road]}\n")
    code = cli_main(["train", str(cfg), "--steps", "10", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 2
    assert err.startswith("madsim: error:") and "trakcs" in err and len(err.strip().splitlines()) == 1
