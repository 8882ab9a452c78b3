"""`madsim plot`: learning curves drawn from a run folder's CSV files."""

import csv
import math

import pytest

from madsim.cli import main as cli_main
from madsim.render.learning_curves import plot_learning_curves, read_csv_columns

EVAL = [  # timesteps, wall_s, lap_fraction, avg_speed_kmh, completion_rate, mean_return, mean_steps
    (0, 1.0, 0.01, 0.3, 0.0, 51.0, 3000), (10000, 20.0, 0.45, 90.0, 0.0, 2400.0, 520),
    (20000, 40.0, 1.0, 80.0, 1.0, 5500.0, 1300),
]


def _write_run(folder, with_progress=True):
    with open(folder / "eval.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["timesteps", "wall_s", "lap_fraction", "avg_speed_kmh", "completion_rate",
                    "mean_return", "mean_steps"])
        w.writerows(EVAL)
    if with_progress:   # SB3's layout: sparse columns, empty cells where a key was not logged
        (folder / "progress.csv").write_text(
            "time/total_timesteps,rollout/ep_rew_mean,train/loss\n"
            "2048,,0.5\n4096,1200.0,0.4\n8192,2300.5,0.3\n")


def test_learning_curves_png_is_written(tmp_path):
    import matplotlib.image

    _write_run(tmp_path)
    out = plot_learning_curves(tmp_path, tmp_path / "curves" / "lc.png")
    assert out == tmp_path / "curves" / "lc.png"
    image = matplotlib.image.imread(out)
    assert image.shape[:2] == (770, 1100)          # 10 x 7 inches at 110 dpi
    assert image[..., :3].std() > 0.05              # something was drawn, not a blank canvas


def test_default_output_is_inside_the_run_folder_and_progress_is_optional(tmp_path, capsys):
    _write_run(tmp_path, with_progress=False)
    assert cli_main(["plot", str(tmp_path)]) == 0
    assert (tmp_path / "learning_curves.png").is_file()
    assert "learning_curves.png" in capsys.readouterr().out


def test_csv_columns_keep_empty_cells_as_nan(tmp_path):
    _write_run(tmp_path)
    cols = read_csv_columns(tmp_path / "progress.csv")
    assert cols["time/total_timesteps"] == [2048.0, 4096.0, 8192.0]
    assert math.isnan(cols["rollout/ep_rew_mean"][0]) and cols["rollout/ep_rew_mean"][1:] == [1200.0, 2300.5]


def test_a_folder_without_evaluations_is_refused(tmp_path, capsys):
    with pytest.raises(FileNotFoundError, match="no eval.csv"):
        plot_learning_curves(tmp_path)
    assert cli_main(["plot", str(tmp_path)]) == 2
    assert "no eval.csv" in capsys.readouterr().err
    (tmp_path / "eval.csv").write_text("timesteps,lap_fraction\n")
    with pytest.raises(ValueError, match="no evaluation rows"):
        plot_learning_curves(tmp_path)
