"""Table 2 from rendered images, one SceneScore row per semantic encoder, at tiny sizes."""

from __future__ import annotations

import torch

from scenescore.cli import main
from scenescore.encoders import make_encoder
from scenescore.experiments import novel
from scenescore.experiments.execution import Execution
from scenescore.vision.graph import graphs_from_renders


def test_novel_from_images_gives_one_scenescore_row_per_encoder():
    torch.manual_seed(0)
    built: list[str] = []

    def scenes_fn(train, test, encoder):
        built.append(encoder.name)
        return graphs_from_renders(train, encoder=encoder), graphs_from_renders(test, encoder=encoder)

    res = novel.run(
        seeds=1,
        methods=["SceneScore", "Oracle"],
        quick=True,
        rules=("class_size",),
        n_test=1,
        n_train=3,
        encoders=[make_encoder("footprint"), make_encoder("image")],
        scenes_fn=scenes_fn,
        execution=Execution(progress=False, log=lambda s: None),
    )
    rows = {r.method: r for r in res.rows()}
    assert list(rows) == ["SceneScore (footprint)", "SceneScore (image)", "Oracle"]
    assert built == ["footprint", "image"]  # the Oracle reuses the first encoder's graphs
    for r in rows.values():
        assert r.figures["class_size_cm"] >= 0 and r.figures["mean_cm"] == r.figures["class_size_cm"]
    assert rows["Oracle"].figures["class_size_cm"] < 2.0  # poses from the images, truth from the simulator
    assert rows["SceneScore (image)"].paper == novel.PAPER["SceneScore"]
    md = novel.format_novel(res, ("class_size",))
    assert "| SceneScore (footprint) |" in md and "| SceneScore (image) |" in md


def test_experiment_rejects_unknown_encoders(tmp_path, capsys):
    rc = main(["experiment", "novel", "--encoders", "image,nope", "--quiet", "--out", str(tmp_path)])
    assert rc != 0
    assert "nope" in capsys.readouterr().err
