"""The package's imports run one way: scene -> encoders -> models -> costs -> problem -> solvers ->
problem files -> training / placement -> experiments -> CLI. No cycles, no upward import, and no
private name imported from another module. Read from the source (every import, also inside functions)."""

from __future__ import annotations

import ast
from pathlib import Path

PKG = Path(__file__).resolve().parents[1] / "scenescore"

# the layer of each module (the longest matching prefix wins); a module may import its own layer or below
LAYERS: list[tuple[str, int]] = [
    ("scenescore.errors", 0),  # settings errors and range checks (imports nothing of the package)
    ("scenescore.textfiles", 0),  # bounded, decoded reading of JSON and YAML files
    ("scenescore.memory", 0),  # the memory budget, the checks made before large allocations, chunk sizes
    ("scenescore.threads", 0),  # the run's torch thread budget, the count chosen per batch, scoped setting
    ("scenescore.devices", 0),  # the device a model, a problem and its random numbers live on
    ("scenescore.workers", 0),  # worker processes that exit with the run that started them
    ("scenescore.provenance", 0),  # where a result came from: commit, date, versions, device, cores
    ("scenescore.tasks", 0),  # an experiment's tasks, their JSON records, sweeps that resume from them
    ("scenescore.scene_fields", 0),  # a scene's JSON fields read and checked; SceneError
    ("scenescore.outputs", 0),  # files written atomically; WriteError
    ("scenescore.scene", 0),
    ("scenescore.units", 0),  # the length unit a dataset names, and lengths said in it
    ("scenescore.geometry", 1),
    ("scenescore.exact", 1),
    ("scenescore.vision", 1),  # imaging primitives: render, segment, pose, crop, sprites
    ("scenescore.encoders", 2),
    ("scenescore.encoders.efficientnet", 2),  # as clip: the pretrained extra imported only when built
    ("scenescore.vision.graph", 3),  # scene graphs from images (encodes crops)
    ("scenescore.models", 3),
    ("scenescore.models.export", 3),  # ONNX export of the energy (onnx imported only when called)
    ("scenescore.models.bundled", 3),  # the pretrained models shipped as package data, by name
    ("scenescore.sampling", 4),
    ("scenescore.costs", 5),
    ("scenescore.costs.relation", 5),  # a learned relation model bound to named objects of a scene
    ("scenescore.problem", 6),
    ("scenescore.scenarios", 7),
    ("scenescore.scenarios.zoo", 7),  # one module per zoo scenario on common.py (ZooScenario)
    ("scenescore.scenarios.relations", 7),  # spatial relations: exact checkers, example generators
    ("scenescore.scenarios.relation_problems", 7),  # random consistent problems of relations, solved-checks
    ("scenescore.solvers", 8),
    ("scenescore.solvers.alm", 8),  # the batched augmented Lagrangian refinement
    ("scenescore.problem_file", 9),
    ("scenescore.learn", 10),  # training the energy: settings, counter-examples, losses, the loop
    ("scenescore.learn.training_state", 10),  # what a training run writes every so often, to resume from
    ("scenescore.learn.workflow", 10),  # `scenescore train`'s workflow: evaluates and calibrates tidying
    ("scenescore.placement", 10),
    ("scenescore.tidying", 10),  # tidying a messy scene: effort, selection, pruning, the pick-and-place plan
    ("scenescore.evaluation", 10),
    ("scenescore.heatmap", 10),
    ("scenescore.plot", 10),
    ("scenescore.baselines", 10),
    ("scenescore.experiments", 11),
    ("scenescore.experiments.bundled", 11),  # the figure each pretrained model is documented with
    ("scenescore.experiments.relations", 11),  # summed relation energies on random problems, per N
    ("scenescore.experiments.relation_models", 11),  # one model per relation, kept when its edge is sharp
    ("scenescore.experiments.relation_methods", 11),  # how each relations method solves one problem
    ("scenescore.cli", 12),
    ("scenescore.cli.export", 12),  # `scenescore export`
    ("scenescore.cli.reference", 12),  # the command-line reference page, rendered from the parser
    ("scenescore.__main__", 12),
    ("scenescore", 12),  # the package's own __init__: the public face, above everything
]


def module_name(path: Path) -> str:
    parts = list(path.relative_to(PKG.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def modules() -> dict[str, Path]:
    return {module_name(p): p for p in PKG.rglob("*.py")}


def layer(mod: str) -> int:
    best = max((p for p, _ in LAYERS if mod == p or mod.startswith(p + ".")), key=len)
    return dict(LAYERS)[best]


def imports(mod: str, path: Path, known: set[str]) -> list[tuple[str, list[str], int]]:
    """``(imported module, names, line)`` for every import of a scenescore module in ``path``."""
    is_pkg = path.name == "__init__.py"
    base = mod.split(".") if is_pkg else mod.split(".")[:-1]
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out += [(a.name, [], node.lineno) for a in node.names if a.name.split(".")[0] == "scenescore"]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                root = base[: len(base) - node.level + 1]
                target = ".".join(root + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target.split(".")[0] != "scenescore":
                continue
            names = [a.name for a in node.names]
            # "from pkg import submodule" imports the submodule
            subs = [f"{target}.{n}" for n in names if f"{target}.{n}" in known]
            if subs:
                out += [(s, [], node.lineno) for s in subs]
                names = [n for n in names if f"{target}.{n}" not in known]
            if names:
                out.append((target, names, node.lineno))
    return out


def graph() -> dict[str, list[tuple[str, list[str], int]]]:
    mods = modules()
    return {m: imports(m, p, set(mods)) for m, p in mods.items()}


def test_every_module_has_a_layer():
    for m in modules():
        layer(m)  # raises if no prefix matches


def test_no_upward_import():
    bad = []
    for m, edges in graph().items():
        for target, _, line in edges:
            if target != m and layer(target) > layer(m):
                bad.append(f"{m}:{line} imports {target} (layer {layer(target)} > {layer(m)})")
    assert not bad, "\n".join(bad)


def test_no_private_name_imported_across_modules():
    bad = []
    for m, edges in graph().items():
        for target, names, line in edges:
            for n in names:
                if n.startswith("_") and not n.startswith("__") and target != m:
                    bad.append(f"{m}:{line} imports private {n!r} from {target}")
    assert not bad, "\n".join(bad)


def test_no_import_cycle():
    g = {m: sorted({t for t, _, _ in edges if t != m and t in graph_keys}) for m, edges in graph().items()}
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(m: str) -> list[str] | None:
        state[m] = 1
        stack.append(m)
        for t in g.get(m, []):
            if state.get(t) == 1:
                return stack[stack.index(t) :] + [t]
            if t not in state:
                found = visit(t)
                if found:
                    return found
        stack.pop()
        state[m] = 2
        return None

    for m in g:
        if m not in state:
            cycle = visit(m)
            assert cycle is None, "import cycle: " + " -> ".join(cycle)


graph_keys = set(modules())


def test_the_checks_can_fail(tmp_path):
    """The walker sees relative imports, function-level imports and private names."""
    src = "from ..solvers.base import _x\n\ndef f():\n    from ..experiments import missing\n"
    p = tmp_path / "mod.py"
    p.write_text(src)
    edges = imports("scenescore.costs.mod", p, {"scenescore.experiments.missing"})
    assert ("scenescore.solvers.base", ["_x"], 1) in edges
    assert ("scenescore.experiments.missing", [], 4) in edges
    assert layer("scenescore.experiments.missing") > layer("scenescore.costs.mod")
