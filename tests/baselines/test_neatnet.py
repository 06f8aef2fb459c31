"""NeatNet: the masked graph VAE fills missing poses and samples whole arrangements."""

import numpy as np
import pytest
import torch

from scenescore.evaluation.baselines import NeatNet, NeatNetConfig
from scenescore.scenarios.tv import TVScenario
from scenescore.scene.scene import SceneError


@pytest.fixture(scope="module")
def fitted():
    torch.set_num_threads(1)
    sc = TVScenario()
    train, test = sc.split(0)
    return sc, test, NeatNet(config=NeatNetConfig(iterations=150)).fit(train, seed=0)


def test_predict_fills_missing_pose_inside_room(fitted):
    sc, test, nn = fitted
    scene = test[0].without("speaker_1")
    out = nn.predict([scene])[0]
    pose = out["speaker_1"].pose
    assert pose is not None
    assert abs(pose[0]) <= 2.5 and abs(pose[1]) <= 2.5
    assert out["television"].pose == scene["television"].pose  # known poses untouched


def test_samples_vary_and_keep_clutter(fitted):
    sc, test, nn = fitted
    scene = sc.clutter(test[0], 2, seed=3)
    poses = nn.sample(scene, 50, seed=0)
    assert poses.shape == (50, len(scene), 3)
    clutter = [scene.index(f"clutter_{i}") for i in range(2)]
    assert np.allclose(poses[:, clutter], scene.poses()[clutter])
    assert poses[:, scene.index("television"), :2].std(0).max() > 0.05  # the latent matters


def test_unfitted_raises():
    with pytest.raises(SceneError):
        NeatNet().predict(TVScenario().generate(1, 0))


def test_missing_experiment_has_neatnet_row():
    from scenescore.experiments import missing
    from scenescore.experiments.execution import Execution

    quiet = Execution(progress=False, log=lambda s: None)
    res = missing.run(seeds=1, methods=["NeatNet"], quick=True, execution=quiet)
    (row,) = res.rows()
    assert row.method == "NeatNet" and row.paper["mean_t_cm"] == 21.7
    assert 0 < row.figures["mean_t_cm"] < 200 and 0 <= row.figures["mean_R_deg"] <= 180
