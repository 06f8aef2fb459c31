"""``scenescore train``'s settings from a YAML file (``--config``) and ``--set key=value`` overrides.

Every :class:`~scenescore.learn.TrainConfig` field is a key; the fields of its ``network``
(:class:`~scenescore.learn.NetworkConfig`) and ``chain`` (:class:`~scenescore.solvers.kernel.LangevinConfig`)
are keys as ``network.hidden`` and ``chain.steps`` (a config file may also nest them as mappings).
An unknown key is refused with the nearest valid one named; a value of the wrong type with the type.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import fields, replace
from typing import Any

from ..errors import ConfigError, nearest_name
from ..learn import NetworkConfig, TrainConfig
from ..scene.textfiles import check_yaml_depth, check_yaml_tree, read_text
from ..solvers.kernel import LangevinConfig

__all__ = ["setting_keys", "parse_overrides", "read_config", "build_config", "overridden"]

NESTED = {"network": NetworkConfig, "chain": LangevinConfig}  # TrainConfig fields that are dataclasses


def _types() -> dict[str, str]:
    """Every key and its field's annotation (a string: the modules use postponed annotations)."""
    out: dict[str, str] = {}
    for f in fields(TrainConfig):
        if f.name in NESTED:
            out.update({f"{f.name}.{g.name}": str(g.type) for g in fields(NESTED[f.name])})
        else:
            out[f.name] = str(f.type)
    return out


def setting_keys() -> list[str]:
    """Every key ``--set`` and ``--config`` accept, in the order the dataclasses declare them."""
    return list(_types())


def _checked(key: str, value: Any, source: str) -> Any:
    """``value`` for ``key`` after checking the key and the value's type (ranges are TrainConfig's)."""
    types = _types()
    if key in NESTED:
        raise ConfigError(f"{source}: {key}: expected a mapping of its settings (or keys such as {key}.KEY)")
    if key not in types:
        names = list(types) + ([] if "." in key else list(NESTED))
        near = nearest_name(key, names, cutoff=0.0)
        raise ConfigError(f"{source}: unknown setting {key!r}; the nearest valid one is {near!r}")
    ann = types[key]
    if value is None:
        if "None" in ann:
            return None
        raise ConfigError(f"{source}: {key}: expected a value of type {ann}, got null")
    if ann.startswith("tuple"):
        ok = isinstance(value, list) and len(value) == 2
        ok = ok and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
        if not ok:
            raise ConfigError(f"{source}: {key}: expected two numbers such as [0.05, 2.0], got {value!r}")
        return tuple(value)
    kinds = {"bool": (bool,), "int": (int,), "float": (int, float)}
    base = ann.split("|")[0].strip()
    if base == "float" and isinstance(value, str):  # YAML 1.1 reads 1e-3 (no dot) as a string
        try:
            value = float(value)
        except ValueError:
            pass
    if base in kinds and (not isinstance(value, kinds[base]) or (base != "bool" and isinstance(value, bool))):
        raise ConfigError(f"{source}: {key}: expected a value of type {ann}, got {value!r}")
    if base not in kinds and not isinstance(value, str):  # a Literal: the class checks the choice
        raise ConfigError(f"{source}: {key}: expected one of {ann}, got {value!r}")
    return value


def parse_overrides(items: list[str]) -> dict[str, Any]:
    """``--set key=value`` items as settings, each value read as YAML (``0.3``, ``true``, ``null``,
    ``[0.05, 2.0]``: :func:`scenescore.cli.key_value`); a later item for the same key wins."""
    from . import key_value

    out: dict[str, Any] = {}
    for item in items:
        try:
            key, value = key_value(item, "feature_noise=0.3")
        except ValueError as e:
            raise ConfigError(f"--set {item!r}: {e}") from None
        out[key] = _checked(key, value, f"--set {item}")
    return out


def _flatten(data: Mapping[str, Any], source: str) -> dict[str, Any]:
    """A config file's mapping with ``network`` and ``chain`` mappings as dotted keys, each checked."""
    out: dict[str, Any] = {}
    for key, value in data.items():
        if not isinstance(key, str):
            raise ConfigError(f"{source}: keys must be names, got {key!r}")
        if key in NESTED and isinstance(value, Mapping):
            for k, v in value.items():
                out[f"{key}.{k}"] = _checked(f"{key}.{k}", v, source)
        else:
            out[key] = _checked(key, value, source)
    return out


def read_config(path: str | os.PathLike) -> dict[str, Any]:
    """A YAML mapping of settings (``--config``), read through the bounded reader of every text file."""
    import yaml

    source = str(path)
    text = read_text(path, ConfigError, "config file")
    try:
        check_yaml_depth(text, source, ConfigError)
        node = yaml.compose(text)
        if node is not None:
            check_yaml_tree(node, source, ConfigError)
        data = yaml.safe_load(text)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        at = f":{mark.line + 1}" if mark else ""
        raise ConfigError(f"{source}{at}: not valid YAML: {' '.join(str(e).split())}") from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError(f"{source}: expected a mapping of settings, got {type(data).__name__}")
    return _flatten(data, source)


def build_config(*layers: Mapping[str, Any]) -> TrainConfig:
    """A :class:`TrainConfig` from settings (dotted keys), later layers overriding earlier ones; the
    fields no layer sets keep their defaults."""
    merged: dict[str, Any] = {}
    for layer in layers:
        merged.update(layer)
    return overridden(TrainConfig(), merged)


def overridden(cfg: TrainConfig, settings: Mapping[str, Any]) -> TrainConfig:
    """``cfg`` with ``settings`` (dotted keys for the ``chain`` and ``network`` fields) changed."""
    top = {k: v for k, v in settings.items() if "." not in k}
    nested = {
        name: {k.split(".", 1)[1]: v for k, v in settings.items() if k.startswith(name + ".")}
        for name in NESTED
    }
    chain = replace(top.pop("chain", cfg.chain), **nested["chain"])
    network = replace(top.pop("network", cfg.network), **nested["network"])
    return replace(cfg, **top, chain=chain, network=network)
