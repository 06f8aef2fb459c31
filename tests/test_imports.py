"""The package's imports run one way: runtime -> scene -> geometry -> vision -> encoders -> models ->
costs -> problem -> scenarios -> solvers -> problem files -> learn -> planning -> evaluation -> viz ->
workflow -> experiments -> CLI. No cycles, no upward import, no private name imported from another
module, and the core (everything below learn) reaches the runtime only through ``scenescore.runtime``
itself. Read from the source (every import, also inside functions)."""

from __future__ import annotations

import ast
from pathlib import Path

PKG = Path(__file__).resolve().parents[1] / "scenescore"

# the layer of each module (the longest matching prefix wins); a module may import its own layer or below
LAYERS: list[tuple[str, int]] = [
    ("scenescore.errors", 0),  # settings errors and range checks (imports nothing of the package)
    (
        "scenescore.runtime",
        0,
    ),  # devices, threads, memory, worker processes: the only part that knows the machine
    ("scenescore.scene", 1),  # scenes, their fields, units, text files read and outputs written
    ("scenescore.geometry", 2),  # poses and footprints in batched torch; the exact shapely/fcl checks
    ("scenescore.vision", 2),  # imaging primitives: render, segment, pose, crop, sprites
    ("scenescore.encoders", 3),
    ("scenescore.encoders.efficientnet", 3),  # as clip: the pretrained extra imported only when built
    ("scenescore.vision.graph", 4),  # scene graphs from images (encodes crops)
    ("scenescore.models", 4),
    ("scenescore.models.export", 4),  # ONNX export of the energy (onnx imported only when called)
    ("scenescore.models.bundled", 4),  # the pretrained models shipped as package data, by name
    ("scenescore.costs", 5),
    ("scenescore.costs.relation", 5),  # a learned relation model bound to named objects of a scene
    ("scenescore.problem", 6),
    ("scenescore.scenarios", 7),
    ("scenescore.scenarios.zoo", 7),  # one module per zoo scenario on common.py (ZooScenario)
    ("scenescore.scenarios.relations", 7),  # spatial relations: exact checkers, example generators
    ("scenescore.scenarios.relation_problems", 7),  # random consistent problems of relations, solved-checks
    ("scenescore.solvers", 8),  # the one Langevin kernel (kernel.py), the stages, chains, results
    ("scenescore.solvers.alm", 8),  # the batched augmented Lagrangian refinement
    ("scenescore.problem.files", 9),  # YAML problem files: they name their solvers
    ("scenescore.learn", 10),  # training the energy: settings, counter-examples, losses, the loop
    ("scenescore.learn.training_state", 10),  # what a training run writes every so often, to resume from
    ("scenescore.planning", 11),  # placement, the heatmap, tidying
    ("scenescore.evaluation", 12),  # the missing-object protocol, the leave-one-object-out report
    ("scenescore.evaluation.baselines", 12),  # nearest neighbour, NeatNet, NeatNet-R
    ("scenescore.viz", 13),  # all drawing
    ("scenescore.workflow", 14),  # `scenescore train`'s workflow: holds out, evaluates, calibrates tidying
    ("scenescore.experiments", 15),
    ("scenescore.experiments.bundled", 15),  # the figure each pretrained model is documented with
    ("scenescore.experiments.relations", 15),  # summed relation energies on random problems, per N
    ("scenescore.experiments.relation_models", 15),  # one model per relation, kept when its edge is sharp
    ("scenescore.experiments.relation_methods", 15),  # how each relations method solves one problem
    ("scenescore.experiments.tasks", 15),  # an experiment's tasks, their records, sweeps that resume
    ("scenescore.experiments.cluster", 15),  # tasks as SLURM jobs through submitit
    ("scenescore.cli", 16),
    ("scenescore.cli.export", 16),  # `scenescore export`
    ("scenescore.cli.reference", 16),  # the command-line reference page, rendered from the parser
    ("scenescore.__main__", 16),
    ("scenescore", 16),  # the package's own __init__: the public face, above everything
]
#: the layers below training reach the runtime only through its package's own names (scenescore.runtime)
CORE_BELOW = 10
RUNTIME = "scenescore.runtime"
#: the most modules the package's root may hold (beside its sub-packages)
ROOT_MODULES = 6


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


def test_the_core_reaches_the_runtime_through_its_one_interface():
    """Below training, an import of the runtime names ``scenescore.runtime`` itself, and only the names
    its ``__all__`` lists: no module of it, no other name."""
    import scenescore.runtime as runtime

    allowed = set(runtime.__all__)
    bad = []
    for m, edges in graph().items():
        if layer(m) >= CORE_BELOW or m == RUNTIME or m.startswith(RUNTIME + "."):
            continue
        for target, names, line in edges:
            if target.startswith(RUNTIME + "."):
                bad.append(f"{m}:{line} imports {target} (import from {RUNTIME} itself)")
            elif target == RUNTIME and (not names or set(names) - allowed):
                bad.append(
                    f"{m}:{line} imports {sorted(set(names) - allowed) or 'the module'} from {RUNTIME}"
                )
    assert not bad, "\n".join(bad)


def test_the_root_holds_few_modules():
    """At most ROOT_MODULES modules at the package's root: the rest live in the sub-packages that name
    the flow."""
    loose = sorted(p.name for p in PKG.glob("*.py"))
    assert len(loose) <= ROOT_MODULES, loose


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
