"""Reading the text files users give (scenes, datasets, problems) within stated bounds.

Every reader here refuses, with one line naming the file: a folder or a device where a file was
expected, a file larger than the cap (``SCENESCORE_MAX_FILE_MB``, default 512 MB, read no further
than the cap so that ``/dev/zero`` ends too), bytes that are not UTF-8 (with the line), JSON or YAML
nested deeper than a scene ever is, duplicate keys (which JSON and YAML would otherwise resolve
silently, last one winning), and YAML whose aliases expand into more nodes than any problem needs
(a "billion laughs").
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

__all__ = [
    "MAX_FILE_MB_ENV",
    "MAX_DEPTH",
    "MAX_YAML_NODES",
    "max_file_bytes",
    "read_text",
    "loads_json",
    "check_yaml_depth",
    "check_yaml_tree",
]

MAX_FILE_MB_ENV = "SCENESCORE_MAX_FILE_MB"
DEFAULT_MAX_FILE_MB = 512.0
MAX_DEPTH = 64  # nesting of JSON/YAML containers; a scene is 4 deep, a problem about 6
MAX_YAML_NODES = 200_000  # YAML nodes after alias expansion; a 200-object problem has about 5000


def max_file_bytes() -> int:
    """The size cap on files read, in bytes: ``SCENESCORE_MAX_FILE_MB`` or 512 MB."""
    raw = os.environ.get(MAX_FILE_MB_ENV)
    try:
        mb = DEFAULT_MAX_FILE_MB if raw is None else float(raw)
    except ValueError:
        mb = -1.0
    if not mb > 0:
        from ..errors import ConfigError

        raise ConfigError(f"{MAX_FILE_MB_ENV}: expected a size in MB > 0, got {raw!r}")
    return int(mb * 2**20)


def read_text(path: str | os.PathLike, error: type[Exception], what: str = "file") -> str:
    """The UTF-8 text of ``path`` (a byte-order mark is dropped); ``error`` is raised for a missing
    path, a folder, a file over the cap and bytes that are not UTF-8, naming the file."""
    p = Path(path)
    if not p.exists():
        raise error(f"{p}: no such {what}")
    if p.is_dir():
        raise error(f"{p}: is a folder; expected a {what}")
    cap = max_file_bytes()
    try:
        with p.open("rb") as f:
            data = f.read(cap + 1)
    except OSError as e:
        raise error(f"{p}: cannot read the {what}: {e.strerror or e}") from None
    if len(data) > cap:
        raise error(
            f"{p}: larger than the {cap / 2**20:g} MB read limit; expected a {what} "
            f"(set {MAX_FILE_MB_ENV} to raise the limit)"
        )
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        line = data[: e.start].count(b"\n") + 1
        raise error(
            f"{p}:{line}: not UTF-8 text (byte {e.start}: {data[e.start : e.start + 1]!r}); "
            f"save the {what} as UTF-8"
        ) from None


class _Duplicate(Exception):
    def __init__(self, key: str):
        self.key = key


def _no_duplicates(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in pairs:
        if k in out:
            raise _Duplicate(k)
        out[k] = v
    return out


def _depth(value: Any) -> int:
    """The nesting depth of parsed JSON (0 for a scalar), without recursion."""
    deepest, stack = 0, [(value, 0)]
    while stack:
        v, d = stack.pop()
        if isinstance(v, dict):
            v = list(v.values())
        if isinstance(v, list):
            deepest = max(deepest, d + 1)
            if d + 1 <= MAX_DEPTH:
                stack.extend((x, d + 1) for x in v)
    return deepest


def loads_json(text: str, path: str, error: type[Exception], line: int | None = None) -> Any:
    """Parse JSON from ``path`` (at ``line`` of a ``.jsonl``); ``error`` names the file and line for bad
    syntax, a duplicate key, or nesting deeper than :data:`MAX_DEPTH`."""
    where = path if line is None else f"{path}:{line}"
    try:
        data = json.loads(text, object_pairs_hook=_no_duplicates)
    except json.JSONDecodeError as e:
        at = where if line is not None else f"{path}:{e.lineno}"
        raise error(f"{at}: not valid JSON: {e.msg} (column {e.colno})") from None
    except _Duplicate as e:
        raise error(f"{where}: duplicate key {e.key!r} in one JSON object; keys must be unique") from None
    except RecursionError:
        raise error(f"{where}: JSON nested deeper than {MAX_DEPTH} levels; a scene is 4 deep") from None
    if _depth(data) > MAX_DEPTH:
        raise error(f"{where}: JSON nested deeper than {MAX_DEPTH} levels; a scene is 4 deep")
    return data


def check_yaml_depth(text: str, source: str, error: type[Exception]) -> None:
    """Refuse YAML nested deeper than :data:`MAX_DEPTH` from its event stream, before any tree is built
    (building one thousands of levels deep is slow and recursive)."""
    import yaml

    depth = 0
    for ev in yaml.parse(text, Loader=yaml.SafeLoader):
        if isinstance(ev, (yaml.MappingStartEvent, yaml.SequenceStartEvent)):
            depth += 1
            if depth > MAX_DEPTH:
                raise error(f"{source}:{ev.start_mark.line + 1}: YAML nested deeper than {MAX_DEPTH} levels")
        elif isinstance(ev, (yaml.MappingEndEvent, yaml.SequenceEndEvent)):
            depth -= 1


def check_yaml_tree(node: Any, source: str, error: type[Exception]) -> None:
    """Walk a composed YAML node graph as the loader would expand it: refuse more than
    :data:`MAX_YAML_NODES` nodes (aliases counted each time they are used), nesting deeper than
    :data:`MAX_DEPTH`, and duplicate keys in a mapping (naming the line)."""
    import yaml

    seen, stack = 0, [(node, 1)]
    while stack:
        n, d = stack.pop()
        seen += 1
        if seen > MAX_YAML_NODES:
            raise error(
                f"{source}: the YAML expands to more than {MAX_YAML_NODES} nodes (anchors and aliases "
                "repeated); a problem file needs far fewer"
            )
        if d > MAX_DEPTH:
            raise error(f"{source}:{n.start_mark.line + 1}: YAML nested deeper than {MAX_DEPTH} levels")
        if isinstance(n, yaml.MappingNode):
            keys: set[str] = set()
            for k, v in n.value:
                if isinstance(k, yaml.ScalarNode):
                    if k.value in keys:
                        raise error(
                            f"{source}:{k.start_mark.line + 1}: duplicate key {k.value!r}; keys must be unique"
                        )
                    keys.add(k.value)
                stack.append((k, d + 1))
                stack.append((v, d + 1))
        elif isinstance(n, yaml.SequenceNode):
            stack.extend((v, d + 1) for v in n.value)
