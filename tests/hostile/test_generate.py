"""``scenescore generate`` at hostile sizes: the JSONL is written as the scenes are drawn (memory that of
one scene, a progress bar), the same file as the scenario's one call; a size that cannot be written (the
--n range, the free disk, the memory budget of the images) is refused with one line before any output."""

from __future__ import annotations

import json
import shutil
from types import SimpleNamespace

import pytest

from scenescore.scenarios import available, get
from scenescore.scene.scene import read_jsonl, write_jsonl

from .helpers import cli_error, run_cli, write


def _without_unit(line: str) -> dict:
    """A written scene as data, without the ``meta.unit`` that ``generate`` adds to a scenario's scenes."""
    d = json.loads(line)
    d["meta"].pop("unit", None)
    return d


@pytest.mark.parametrize("n", [5, 40])
def test_generate_writes_the_scenarios_scenes(tmp_path, capsys, n):
    """Small and sampled sizes alike: the file holds the scenario's one call, in order, with a progress
    bar on stderr (none with --quiet)."""
    out = tmp_path / "g.jsonl"
    code, printed, err = run_cli(capsys, "generate", "dining", "--n", n, "--seed", 3, "--out", out)
    assert code == 0 and printed == f"wrote {n} dining scenes to {out}\n"
    assert "generate dining" in err and f"{n}/{n}" in err
    lines = out.read_text().splitlines()
    assert [_without_unit(ln) for ln in lines] == [
        json.loads(s.to_json(indent=None)) for s in get("dining").generate(n, 3)
    ]
    code, _, err = run_cli(capsys, "generate", "dining", "--n", n, "--seed", 3, "--out", out, "--quiet")
    assert code == 0 and err == ""
    assert out.read_text().splitlines() == lines


@pytest.mark.parametrize("name", available())
def test_iter_scenes_are_the_generated_scenes(name):
    """The scenes ``generate`` writes one at a time are those of ``generate``, from the same stream."""
    scenario = get(name)
    drawn = [s.to_json(indent=None) for s in scenario.iter_scenes(3, 11)]
    assert drawn == [s.to_json(indent=None) for s in scenario.generate(3, 11)]
    assert drawn != [s.to_json(indent=None) for s in scenario.generate(3, 12)]


def test_generate_streams_under_a_tiny_memory_budget(tmp_path, capsys):
    """The JSONL alone holds no list of scenes, so a budget far below the scenes' size does not refuse it."""
    out = tmp_path / "g.jsonl"
    code, _, err = run_cli(
        capsys, "generate", "dining", "--n", 1000, "--out", out, "--memory-gb", 0.0005, "--quiet"
    )
    assert code == 0, err
    assert out.stat().st_size > 1_000_000  # over the 0.5 MB budget: it was not held whole
    assert len(read_jsonl(out)) == 1000


def test_generate_an_absurd_number_of_scenes_is_refused(tmp_path, capsys):
    cli_error(
        capsys,
        *("generate", "dining", "--n", "100000000", "--out", tmp_path / "g.jsonl"),
        names=("--n", "100000000"),
    )
    assert not (tmp_path / "g.jsonl").exists()


def test_generate_larger_than_the_free_disk_is_refused(tmp_path, capsys, monkeypatch):
    """Refused from the first scenes' size before the file is begun; an earlier file stays whole."""
    out = write(tmp_path / "g.jsonl", "earlier\n")
    monkeypatch.setattr(shutil, "disk_usage", lambda _: SimpleNamespace(total=10**9, used=0, free=10**6))
    line = cli_error(
        capsys,
        *("generate", "dining", "--n", "1000", "--out", out),
        names=("generate dining: 1000 scenes", "bytes of JSON each", str(out), "0.001 GB free", "lower --n"),
    )
    assert "0%" not in line
    assert out.read_text() == "earlier\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["g.jsonl"]  # no temporary file left


def test_generate_images_over_the_memory_budget_is_refused(tmp_path, capsys):
    """The images are rendered from the scenes held whole: over the budget, refused before any is made."""
    line = cli_error(
        capsys,
        *("generate", "dining", "--n", "1000", "--images", tmp_path / "img", "--out", tmp_path / "g.jsonl"),
        *("--memory-gb", "0.001"),
        names=("generate dining: 1000 scenes", "memory budget of 0.001 GB (--memory-gb)", "lower --n"),
    )
    assert "bytes of JSON each" in line
    assert not (tmp_path / "img").exists() and not (tmp_path / "g.jsonl").exists()


def test_generate_into_a_folder_is_refused(tmp_path, capsys):
    cli_error(capsys, "generate", "dining", "--out", tmp_path, names=("--out", str(tmp_path), "is a folder"))


def test_interrupted_jsonl_leaves_the_earlier_file(tmp_path):
    """Scenes that stop coming (an error, Ctrl-C) part-way leave the earlier file and no temporary one."""
    out = write(tmp_path / "d.jsonl", "earlier\n")
    scenes = get("dining").generate(3, 0)

    def drawn():
        yield from scenes
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        write_jsonl(out, drawn())
    assert out.read_text() == "earlier\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.jsonl"]
    assert write_jsonl(out, iter(scenes)) == 3
    assert [s.to_json() for s in read_jsonl(out)] == [s.to_json() for s in scenes]
