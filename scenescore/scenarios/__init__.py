"""Data-generating processes: seeded scene generators, each with an oracle where one is defined."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

from ..scene.scene import Scene, SceneError
from .desk import DeskScenario
from .dining import DiningScenario
from .ordering import OrderingScenario
from .relations import SCENARIOS as RELATION_SCENARIOS
from .relations import RelationScenario
from .tv import TVScenario
from .zoo import SCENARIOS as ZOO_SCENARIOS
from .zoo import (
    ZOO,
    BanquetScenario,
    BedroomScenario,
    BookshelfScenario,
    CafeScenario,
    CascadeScenario,
    ClassroomScenario,
    GardenScenario,
    HallScenario,
    JarGridScenario,
    LoungeScenario,
    PcbScenario,
    WorkstationScenario,
)

__all__ = [
    "Scenario",
    "register",
    "get",
    "available",
    "describe",
    "DiningScenario",
    "OrderingScenario",
    "TVScenario",
    "DeskScenario",
    "ZOO",
    "PcbScenario",
    "JarGridScenario",
    "BedroomScenario",
    "BanquetScenario",
    "WorkstationScenario",
    "GardenScenario",
    "CascadeScenario",
    "BookshelfScenario",
    "LoungeScenario",
    "HallScenario",
    "ClassroomScenario",
    "CafeScenario",
    "RelationScenario",
]


class Scenario(Protocol):
    """A seeded generator of scenes (``generate``), with the experiment's split and an oracle.

    The bundled scenarios also have ``iter_scenes(n, seed)``, ``generate``'s scenes one at a time, which
    ``scenescore generate`` writes as they come; a scenario without it is generated whole, within the
    memory budget."""

    name: str

    def generate(self, n: int, seed: int) -> list[Scene]: ...

    def split(self, seed: int) -> tuple[list[Scene], list[Scene]]: ...

    def oracle(self, scene: Scene, name: str) -> tuple[float, float, float]: ...


_REGISTRY: dict[str, Callable[..., Any]] = {
    "dining": DiningScenario,
    "ordering": OrderingScenario,
    "tv": TVScenario,
    "desk": DeskScenario,
    **ZOO_SCENARIOS,
    **RELATION_SCENARIOS,  # relation-left_of, ...: examples of one spatial relation each
}


def register(name: str, factory: Callable[..., Any]) -> None:
    """Add a scenario under ``name``."""
    _REGISTRY[name] = factory


def available() -> list[str]:
    return sorted(_REGISTRY)


def describe(name: str) -> str:
    """One line on what the scenario ``name`` generates: its docstring's first sentence."""
    if name not in _REGISTRY:
        raise SceneError(f"unknown scenario {name!r}; available: {', '.join(available())}")
    doc = " ".join((_REGISTRY[name].__doc__ or "").split("\n\n")[0].split())
    return doc.split(". ")[0].rstrip(".") + "." if doc else ""


def get(name: str, **options: Any) -> Any:
    """The scenario called ``name``; an unknown name lists the valid ones."""
    if name not in _REGISTRY:
        raise SceneError(f"unknown scenario {name!r}; available: {', '.join(available())}")
    return _REGISTRY[name](**options)
