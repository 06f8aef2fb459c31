"""TensorBoard logs of training: the loss and learning rate of every iteration, then held-out figures."""

import json
import sys

import pytest
import torch

pytest.importorskip("tensorboard")

from tensorboard.backend.event_processing.event_accumulator import EventAccumulator  # noqa: E402

from scenescore.cli import main  # noqa: E402
from scenescore.errors import ConfigError  # noqa: E402
from scenescore.learn import NetworkConfig, Run, TrainConfig, fit  # noqa: E402
from scenescore.learn.config import LR_DENSE
from scenescore.learn.logs import log_validation
from scenescore.scenarios import get  # noqa: E402
from scenescore.scene.scene import write_jsonl  # noqa: E402

CFG = TrainConfig(
    members=1, iterations=4, batch_scenes=4, negatives=4, network=NetworkConfig(hidden=16, layers=1)
)


def _scalars(log_dir):
    acc = EventAccumulator(str(log_dir))
    acc.Reload()
    return {tag: [(e.step, e.value) for e in acc.Scalars(tag)] for tag in acc.Tags()["scalars"]}


def test_training_logs_loss_and_lr_every_iteration(tmp_path):
    torch.set_num_threads(1)
    log = tmp_path / "runs" / "a"
    model = fit(get("tv").generate(4, seed=0), CFG, seed=0, progress=False, run=Run(log_dir=log))
    assert list(log.glob("events.out.tfevents.*"))
    s = _scalars(log)
    assert [step for step, _ in s["train/loss"]] == [0, 1, 2, 3]
    assert [step for step, _ in s["train/infonce"]] == [0, 1, 2, 3]
    lrs = [v for _, v in s["train/lr"]]
    assert lrs[0] == pytest.approx(LR_DENSE) and lrs == sorted(
        lrs, reverse=True
    )  # the dense graph's, decaying
    # the logged losses are the ones training records (its history: means of blocks of 10)
    mean = sum(v for _, v in s["train/loss"]) / 4
    assert mean == pytest.approx(model.info.history[0], abs=1e-4)
    cats = [{"category": "tv", "t_cm": 2.0, "R_deg": 10.0, "baseline_t_cm": None}]
    log_validation(log, {"heldout_loss": 1.5, "mean_t_cm": 3.0, "mean_R_deg": None, "categories": cats}, 3)
    s = _scalars(log)
    assert s["validation/heldout_loss"] == [(3, 1.5)] and s["validation/t_cm/tv"] == [(3, 2.0)]
    assert "validation/mean_R_deg" not in s and "validation/baseline_t_cm/tv" not in s


def test_cli_log_dir(tmp_path, capsys, monkeypatch):
    torch.set_num_threads(1)
    write_jsonl(tmp_path / "d.jsonl", get("tv").generate(4, seed=0))
    write_jsonl(tmp_path / "v.jsonl", get("tv").generate(1, seed=1))
    argv = [
        "train",
        "--members",
        "1",
        str(tmp_path / "d.jsonl"),
        "--out",
        str(tmp_path / "m.ckpt"),
        "--iterations",
        "3",
        "--force",
    ]
    val = ["--val-data", str(tmp_path / "v.jsonl")]
    assert main([*argv, *val, "--log-dir", str(tmp_path / "log"), "--quiet"]) == 0
    s = _scalars(tmp_path / "log")
    assert [step for step, _ in s["train/loss"]] == [0, 1, 2]
    report = json.loads((tmp_path / "train_report.json").read_text())["validation"]
    assert s["validation/heldout_loss"] == [(2, pytest.approx(report["heldout_loss"]))]
    speaker = next(c for c in report["categories"] if c["category"] == "speaker")
    assert s["validation/t_cm/speaker"] == [(2, pytest.approx(speaker["t_cm"]))]
    capsys.readouterr()
    # a log folder that is a file, and tensorboard missing: one line, before any training
    (tmp_path / "afile").write_text("x")
    out = tmp_path / "n.ckpt"
    argv[argv.index("--out") + 1] = str(out)
    assert main([*argv, "--log-dir", str(tmp_path / "afile"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "--log-dir" in err and "expected a folder" in err and len(err.strip().splitlines()) == 1
    monkeypatch.setitem(sys.modules, "torch.utils.tensorboard", None)  # as if not installed
    assert main([*argv, "--log-dir", str(tmp_path / "log2"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "'tensorboard' extra" in err and len(err.strip().splitlines()) == 1
    assert not out.exists() and not (tmp_path / "log2").exists()
    with pytest.raises(ConfigError, match="'tensorboard' extra"):
        fit(get("tv").generate(2, seed=0), CFG, progress=False, run=Run(log_dir=tmp_path / "log3"))
