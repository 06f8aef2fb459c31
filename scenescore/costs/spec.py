"""The YAML side of costs: a cost's spec (its keys, checked by pydantic) and the registry of spec types.

A cost module declares a :class:`CostSpec` subclass with ``type: Literal["mytype"]`` and its keys, builds
the cost in :meth:`CostSpec.build`, and calls :func:`register_cost_type`; a problem file's ``costs`` list
is read with the registered specs (:mod:`scenescore.problem.files`).
"""

from __future__ import annotations

from typing import Annotated, Any, Protocol

from pydantic import BaseModel, ConfigDict, Field, PydanticUndefinedAnnotation

from ..scene.fields import MAX_LENGTH
from .base import Cost
from .terms import CostError

__all__ = ["CostSpec", "Coordinate", "SpecContext", "register_cost_type", "cost_types"]


class SpecContext(Protocol):
    """What a cost's YAML spec may ask of the file it is read from (errors name the file, line and key)."""

    def object(self, name: str, at: tuple[str | int, ...]) -> str:
        """``name`` if the scene has such an object, else a :class:`ProblemError` naming ``at``."""
        ...

    def objects(self, names: list[str] | None, at: tuple[str | int, ...]) -> list[str] | None:
        """Each of ``names`` checked as by :meth:`object` (``None`` stays ``None``)."""
        ...

    def model(self, at: tuple[str | int, ...]) -> Any:
        """The problem file's trained model (its top-level ``model`` key), loaded once."""
        ...

    def checkpoint(self, path: str, at: tuple[str | int, ...]) -> Any:
        """The model in the checkpoint at ``path`` (relative to the problem file), loaded once per file."""
        ...


#: a coordinate in metres in a YAML spec: finite and within the range scenes allow
Coordinate = Annotated[float, Field(ge=-MAX_LENGTH, le=MAX_LENGTH)]


class CostSpec(BaseModel):
    """Base of a cost's YAML spec: ``type``, ``weight``, ``name`` and the cost's own keys (no others).

    A subclass declares ``type: Literal["mytype"]`` and the cost's keys, and builds the cost in
    :meth:`build`; :func:`register_cost_type` makes ``type: mytype`` valid in problem files.
    """

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)  # no NaN or inf in any number
    type: str
    weight: float = Field(1.0, ge=0, allow_inf_nan=False)
    name: str | None = None

    def build(self, ctx: SpecContext) -> Cost:  # pragma: no cover - abstract
        raise NotImplementedError

    def named(self) -> dict[str, Any]:
        """``{"name": ...}`` when the spec names the term, else ``{}`` (the cost's default name)."""
        return {"name": self.name} if self.name else {}


_COST_TYPES: dict[str, type[CostSpec]] = {}


def register_cost_type(type_name: str, spec: type[CostSpec]) -> type[CostSpec]:
    """Make ``type: <type_name>`` valid in YAML problem files, read with ``spec``."""
    if not (isinstance(spec, type) and issubclass(spec, CostSpec)):
        raise CostError(f"register_cost_type({type_name!r}): expected a CostSpec subclass, got {spec!r}")
    if not spec.__pydantic_complete__:  # a field's type (a string annotation) not yet resolved
        try:  # resolved now with the caller's names, so that reading a YAML file cannot fail on it later
            spec.model_rebuild(raise_errors=True, _parent_namespace_depth=3)
        except PydanticUndefinedAnnotation as e:
            raise CostError(
                f"register_cost_type({type_name!r}): a field of {spec.__name__} names {e.name!r}, which is "
                f"not defined where {spec.__name__} is; import it there"
            ) from None
    _COST_TYPES[type_name] = spec
    return spec


def cost_types() -> dict[str, type[CostSpec]]:
    """The registered YAML cost types: name -> spec class."""
    return dict(_COST_TYPES)
