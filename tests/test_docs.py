"""The Python snippets of docs/extending.md run as written: compiled as a file of their own (not under this
module's ``from __future__`` imports), their registrations undone when the test ends."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parents[1] / "docs"


def _python_blocks(path: Path) -> list[str]:
    return re.findall(r"```python\n(.*?)```", path.read_text(), flags=re.S)


@pytest.mark.parametrize("doc", ["extending.md"])
def test_python_snippets_run(doc, capsys, own_registries):
    blocks = _python_blocks(DOCS / doc)
    assert blocks, f"{doc} has no python block"
    for code in blocks:
        exec(compile(code, f"{doc}:snippet", "exec", dont_inherit=True), {"__name__": "snippet"})
    assert "solver langevin>casadi" in capsys.readouterr().out


def test_costs_snippets_run(capsys, own_registries):
    """docs/costs.md's learned relation: trained briefly, it prefers the arrangement its checker accepts."""
    blocks = _python_blocks(DOCS / "costs.md")
    assert blocks, "costs.md has no python block"
    for code in blocks:
        exec(compile(code, "costs.md:snippet", "exec", dont_inherit=True), {"__name__": "snippet"})
    out = capsys.readouterr().out
    assert out.startswith("True tensor(")


ROOT = DOCS.parent


@pytest.mark.parametrize("page", ["README.md", *sorted(p.name for p in DOCS.glob("*.md"))])
def test_relative_links_name_files_that_exist(page):
    """A Markdown link that is not a URL or an anchor names a file of the repository (README) or of
    docs/ (the site's pages, which `mkdocs build --strict` checks too)."""
    path = ROOT / page if page == "README.md" else DOCS / page
    prose = re.sub(r"```.*?```|`[^`\n]*`", "", path.read_text(), flags=re.S)  # links in code are code
    for target in re.findall(r"\]\(([^)\s]+)\)", prose):
        if re.match(r"[a-z]+:", target) or target.startswith("#"):
            continue
        assert (path.parent / target.split("#")[0]).exists(), f"{page}: link to missing {target}"


def test_costs_relation_problem_is_the_example_and_loads(tmp_path):
    """docs/costs.md's problem of relations is examples/relations.yaml as it runs (tests/test_examples.py
    solves that file), and loads as written with the shipped relation models."""
    import yaml

    from scenescore.problem.files import load_problem

    blocks = re.findall(r"```yaml\n(.*?)```", (DOCS / "costs.md").read_text(), flags=re.S)
    shown = [b for b in blocks if "relation-left_of" in b]
    assert len(shown) == 1
    example = ROOT / "examples" / "relations.yaml"
    assert yaml.safe_load(shown[0]) == yaml.safe_load(example.read_text())
    (tmp_path / "p.yaml").write_text(shown[0])
    lp = load_problem(tmp_path / "p.yaml")
    assert len(lp.problem.scene) == 5 and lp.solver == "langevin>alm"


def test_costs_example_relations_snippet_runs(tmp_path, monkeypatch):
    """docs/costs.md's ExampleRelations snippet, in a folder holding the files it names."""
    import shutil

    import scenescore as ss

    (code,) = [
        b
        for b in re.findall(r"```text\n(.*?)```", (DOCS / "costs.md").read_text(), flags=re.S)
        if "ExampleRelations" in b
    ]
    shutil.copytree(ROOT / "examples", tmp_path / "examples", ignore=shutil.ignore_patterns("*.ckpt"))
    scenes = ss.scenarios.get("dining").generate(6, 0)
    ss.write_jsonl(tmp_path / "data.jsonl", scenes)
    ss.learn.fit(scenes, ss.learn.TrainConfig(members=1, iterations=3), seed=0, progress=False).save(
        tmp_path / "model.ckpt"
    )
    monkeypatch.chdir(tmp_path)
    space: dict = {"__name__": "snippet"}
    exec(compile(code, "costs.md:snippet", "exec", dont_inherit=True), space)
    result = space["result"]
    assert [name for name, _ in result.terms.items()] == ["energy", "overlap", "examples"]
