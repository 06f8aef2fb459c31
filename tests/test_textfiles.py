"""Hostile text files: every case one clear error naming the file (and line or key), in bounded time and memory."""

from __future__ import annotations

import json

import pytest

from scenescore.cli import main
from scenescore.errors import ConfigError
from scenescore.problem.files import load_problem
from scenescore.problem.problem import ProblemError
from scenescore.scene.scene import Scene, SceneError, read_jsonl
from scenescore.scene.textfiles import MAX_DEPTH, MAX_FILE_MB_ENV, max_file_bytes

SCENE = {
    "bounds": [[-0.5, -0.5], [0.5, 0.5]],
    "objects": [
        {"name": "plate", "category": "plate", "size": [0.2, 0.2], "pose": [0, 0, 0], "shape": "disk"},
        {"name": "fork", "category": "fork", "size": [0.18, 0.02], "pose": [0.2, 0, 0]},
    ],
}


def _write(tmp_path, name, data: bytes | str):
    p = tmp_path / name
    p.write_bytes(data if isinstance(data, bytes) else data.encode())
    return p


@pytest.mark.parametrize(
    "name, payload, needle",
    [
        (
            "latin1.json",
            json.dumps(SCENE).replace("fork", "fourch\xe9tte").encode("latin-1"),
            ":1: not UTF-8",
        ),
        ("dup.json", '{"bounds": [[0, 0], [1, 1]], "bounds": [[0, 0], [2, 2]], "objects": []}', "'bounds'"),
        ("deep.json", "[" * 100_000 + "]" * 100_000, "nested deeper"),
        (
            "deep2.json",
            '{"meta": ' + '{"a": ' * (MAX_DEPTH + 2) + "1" + "}" * (MAX_DEPTH + 3),
            "nested deeper",
        ),
        ("bad.json", '{"objects": [}', "not valid JSON"),
    ],
)
def test_bad_scene_files_name_the_file(tmp_path, name, payload, needle):
    p = _write(tmp_path, name, payload)
    with pytest.raises(SceneError) as e:
        Scene.from_json(p)
    assert str(p) in str(e.value) and needle in str(e.value)


def test_bom_is_accepted(tmp_path):
    p = _write(tmp_path, "bom.json", b"\xef\xbb\xbf" + json.dumps(SCENE).encode())
    assert Scene.from_json(p).names == ["plate", "fork"]


def test_a_folder_where_a_file_was_expected(tmp_path):
    with pytest.raises(SceneError, match="is a folder"):
        Scene.from_json(tmp_path)
    with pytest.raises(SceneError, match="is a folder"):
        read_jsonl(tmp_path)
    with pytest.raises(ProblemError, match="is a folder"):
        load_problem(tmp_path)


def test_endless_files_stop_at_the_cap(monkeypatch, tmp_path):
    monkeypatch.setenv(MAX_FILE_MB_ENV, "1")
    assert max_file_bytes() == 2**20
    for reader in (Scene.from_json, read_jsonl):
        with pytest.raises(SceneError, match="read limit"):
            reader("/dev/zero")
    with pytest.raises(ProblemError, match="read limit"):
        load_problem("/dev/zero")
    big = _write(tmp_path, "big.jsonl", (json.dumps(SCENE) + "\n") * 6000)  # about 1.5 MB
    with pytest.raises(SceneError, match=str(big)):
        read_jsonl(big)
    monkeypatch.setenv(MAX_FILE_MB_ENV, "4")
    assert len(read_jsonl(big)) == 6000
    monkeypatch.setenv(MAX_FILE_MB_ENV, "lots")
    with pytest.raises(ConfigError, match=MAX_FILE_MB_ENV):
        max_file_bytes()


def test_jsonl_errors_name_the_line(tmp_path):
    good = json.dumps(SCENE)
    dup = good.replace('"name": "fork",', '"name": "fork", "name": "knife",')
    p = _write(tmp_path, "d.jsonl", f"{good}\n\n{dup}\n")
    with pytest.raises(SceneError, match=rf"{p}:3: duplicate key 'name'"):
        read_jsonl(p)
    p = _write(tmp_path, "u.jsonl", good.encode() + b"\n" + good.replace("fork", "f\xf6rk").encode("latin-1"))
    with pytest.raises(SceneError, match=rf"{p}:2: not UTF-8"):
        read_jsonl(p)


LAUGHS = "\n".join(
    ["a: &a [x, x, x, x, x, x, x, x, x]"]
    + [
        f"{chr(98 + k)}: &{chr(98 + k)} [*{chr(97 + k)}, *{chr(97 + k)}, *{chr(97 + k)}, *{chr(97 + k)}, *{chr(97 + k)}, *{chr(97 + k)}, *{chr(97 + k)}, *{chr(97 + k)}, *{chr(97 + k)}]"
        for k in range(8)
    ]
    + ["scene: *i", "costs: []"]
)


@pytest.mark.parametrize(
    "name, text, needle",
    [
        ("laughs.yaml", LAUGHS, "expands to more than"),
        ("dup.yaml", "scene: a.json\ncosts: []\nscene: b.json\n", ":3: duplicate key 'scene'"),
        ("deep.yaml", "scene: " + "[" * 5000 + "]" * 5000 + "\ncosts: []\n", "nested deeper"),
        ("latin1.yaml", "scene: a.json\ncosts: []\n# caf\xe9\n", ":3: not UTF-8"),
    ],
)
def test_bad_problem_files_name_the_file(tmp_path, name, text, needle):
    p = _write(tmp_path, name, text.encode("latin-1") if name.startswith("latin1") else text.encode())
    with pytest.raises(ProblemError) as e:
        load_problem(p)
    assert str(p) in str(e.value) and needle in str(e.value)


def test_the_cli_prints_one_line(tmp_path, capsys):
    p = _write(tmp_path, "dup.yaml", "scene: a.json\ncosts: []\nscene: b.json\n")
    assert main(["solve", str(p)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "duplicate key 'scene'" in err[0]
    assert main(["solve", str(tmp_path)]) == 2
    assert "is a folder" in capsys.readouterr().err
