"""The package's shape, checked from its source: no function longer than a screen or two, no public
function with a long argument list (grouped settings instead), and no comment or docstring that dates
itself with a commit or a day (figures and their provenance live in docs/studies.md and the benchmarks)."""

from __future__ import annotations

import ast
import io
import re
import tokenize
from pathlib import Path

PKG = Path(__file__).resolve().parents[1] / "scenescore"
MAX_LINES = 80  # a function, from its def to its last line, docstring included
MAX_PARAMS = 10  # a public function's parameters, self and cls not counted
# a day (2026-11-29) or a commit named as one (at bae9247, commit 1a2b3c4d)
DATED = re.compile(r"\b20\d\d-\d\d-\d\d\b|\b(at|commit|since|before|after) [0-9a-f]{7,40}\b")


def functions(path: Path) -> list[ast.FunctionDef | ast.AsyncFunctionDef]:
    tree = ast.parse(path.read_text())
    return [n for n in ast.walk(tree) if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))]


def params(fn: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    a = fn.args
    n = len(a.posonlyargs) + len(a.args) + len(a.kwonlyargs) + bool(a.vararg) + bool(a.kwarg)
    first = (a.posonlyargs + a.args)[:1]
    return n - (1 if first and first[0].arg in ("self", "cls") else 0)


def long_functions(root: Path) -> list[str]:
    return [
        f"{p.relative_to(root.parent)}:{fn.lineno} {fn.name}: {fn.end_lineno - fn.lineno + 1} lines"
        for p in sorted(root.rglob("*.py"))
        for fn in functions(p)
        if fn.end_lineno is not None and fn.end_lineno - fn.lineno + 1 > MAX_LINES
    ]


def long_signatures(root: Path) -> list[str]:
    return [
        f"{p.relative_to(root.parent)}:{fn.lineno} {fn.name}: {params(fn)} parameters"
        for p in sorted(root.rglob("*.py"))
        for fn in functions(p)
        if not fn.name.startswith("_") and params(fn) > MAX_PARAMS
    ]


def dated_text(root: Path) -> list[str]:
    out = []
    for p in sorted(root.rglob("*.py")):
        for tok in tokenize.generate_tokens(io.StringIO(p.read_text()).readline):
            if tok.type in (tokenize.COMMENT, tokenize.STRING) and DATED.search(tok.string):
                out.append(
                    f"{p.relative_to(root.parent)}:{tok.start[0]}: {DATED.search(tok.string).group(0)}"
                )
    return out


def test_no_function_is_over_the_limit():
    assert not long_functions(PKG), "\n".join(long_functions(PKG))


def test_no_public_function_takes_a_long_argument_list():
    assert not long_signatures(PKG), "\n".join(long_signatures(PKG))


def test_no_comment_or_docstring_names_a_day_or_a_commit():
    assert not dated_text(PKG), "\n".join(dated_text(PKG))


def test_the_checks_can_fail(tmp_path):
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    body = "\n".join(f"    x{i} = {i}" for i in range(MAX_LINES))
    args = ", ".join(f"a{i}" for i in range(MAX_PARAMS + 1))
    (pkg / "m.py").write_text(
        f"def long():\n{body}\n\n\ndef wide({args}):\n    pass\n\n\n"
        f"def _private({args}):\n    pass\n\n\n# measured at bae9247 on 2026-11-29\n"
    )
    assert [s.split(": ")[0] for s in long_functions(pkg)] == ["pkg/m.py:1 long"]
    assert [s.split(": ")[0] for s in long_signatures(pkg)] == [f"pkg/m.py:{MAX_LINES + 4} wide"]
    assert len(dated_text(pkg)) == 1
