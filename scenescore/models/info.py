"""What a trained model records about itself: :class:`ModelInfo`, stored as a checkpoint's ``info``.

Training fills the run's figures and the trust reference; ``scenescore train`` (and ``ss.train``) adds
the held-out evaluation and tidy's calibration. Every field may be missing in a checkpoint (a model
built by hand, or written before the field existed): it is then None, and it is left out of the file.
Keys this version does not know are kept in :attr:`ModelInfo.extra` and written back as they were.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any

from .trust import TrustReference

__all__ = ["ModelInfo", "TidyCalibration", "Caveats"]


@dataclass
class TidyCalibration:
    """What a move must gain to be worth its effort, measured on scenes taken as right
    (``scenescore.planning.tidying.calibrate``). Values are stored as read: the tidy planner checks each before
    it uses it (a damaged file may hold anything)."""

    move_gain: float | None = None  # a quantile of each scene's best single-move gain
    gains: list[float] | None = None  # every object's single-move gain, at least 0, sorted
    scenes: int | None = None  # the scenes measured on
    quantile: float | None = None  # the quantile ``move_gain`` is
    # not yet measured: the scenes taken as right (scene JSON) to measure it on when the model first
    # tidies, and the seed of that search (``scenescore.planning.tidying.calibration.ensure_calibrated``)
    pending: list[dict[str, Any]] | None = None
    seed: int | None = None

    def to_dict(self) -> dict[str, Any]:
        return {f.name: getattr(self, f.name) for f in fields(self) if getattr(self, f.name) is not None}

    def summary(self) -> dict[str, Any]:
        """What a report shows of it: :meth:`to_dict` without the pending scenes' poses, and whether the
        gains are measured yet."""
        out = {k: v for k, v in self.to_dict().items() if k != "pending"}
        return {**out, "measured": self.pending is None}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> TidyCalibration:
        return cls(**{f.name: d.get(f.name) for f in fields(cls)})


@dataclass
class Caveats:
    """What the held-out evaluation found the model has not learned (``EvalReport.caveats()``): every
    placement it concerns carries the reason among its flags (:func:`~scenescore.models.trust.assess`)."""

    model: list[str] = field(default_factory=list)  # reasons every placement carries (loss not below chance)
    categories: dict[str, str] = field(default_factory=dict)  # category -> the reason its placements carry

    def reasons(self, category: str) -> list[str]:
        """The reasons a placed object of ``category`` carries."""
        own = self.categories.get(category)
        return self.model + ([own] if own is not None else [])

    def to_dict(self) -> dict[str, Any]:
        return {"model": list(self.model), "categories": dict(self.categories)}

    @classmethod
    def from_dict(cls, d: Any) -> Caveats:
        """Read stored caveats; anything but lists and mappings of strings raises ``ValueError``."""
        if not isinstance(d, dict):
            raise ValueError(f"expected a mapping, got {type(d).__name__}")
        model, cats = d.get("model", []), d.get("categories", {})
        if not (isinstance(model, list) and all(isinstance(r, str) for r in model)):
            raise ValueError(f"model: expected a list of strings, got {model!r:.80}")
        if not (isinstance(cats, dict) and all(isinstance(r, str) for r in cats.values())):
            raise ValueError(f"categories: expected a mapping of category to string, got {cats!r:.80}")
        return cls(list(model), dict(cats))


@dataclass
class ModelInfo:
    """A trained model's record, in the order a checkpoint stores it."""

    train_config: dict[str, Any] | None = None  # the training settings (``TrainConfig.to_dict()``)
    seed: int | None = None
    scenes: int | None = None  # scenes trained on
    final_loss: float | None = None  # mean training loss over the last 50 iterations
    chance_loss: float | None = None  # the loss of an energy that tells nothing apart: log(1 + K)
    seconds: float | None = None  # training time (an ensemble's: its members' summed)
    compiled: bool | None = None  # whether its network's passes trained compiled (TrainConfig.compile)
    history: list[float] | None = None  # the learning curve: the mean loss of each block of 10 iterations
    trust: TrustReference | None = None  # what placements are judged against
    validation: dict[str, Any] | None = None  # the held-out evaluation (``EvalReport.to_dict()``)
    tidy: TidyCalibration | None = None
    caveats: Caveats | None = None  # what the held-out evaluation found unlearned; None: nothing, or not run
    # an ensemble's members, each's own training record (seed, final_loss, seconds); None: one network
    members: list[dict[str, Any]] | None = None
    # the weights training started from ({"source", "digest"}: fit's init); None: drawn by the seed
    init: dict[str, str] | None = None
    extra: dict[str, Any] = field(default_factory=dict)  # keys of the file this version does not know

    def to_dict(self) -> dict[str, Any]:
        """The JSON object a checkpoint stores: the fields that are set, then :attr:`extra`."""
        out: dict[str, Any] = {}
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name == "extra" or value is None:
                continue
            stored = isinstance(value, (TrustReference, TidyCalibration, Caveats))
            out[f.name] = value.to_dict() if stored else value
        return {**out, **self.extra}

    def training(self) -> dict[str, Any]:
        """The training run's own figures: :meth:`to_dict` without the trust reference, the evaluation
        and the calibration (the ``training`` part of ``train_report.json``)."""
        out = self.to_dict()
        for key in ("trust", "validation", "tidy", "caveats"):
            out.pop(key, None)
        return out

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> ModelInfo:
        """Read a checkpoint's ``info``; a damaged trust reference raises ``ValueError`` naming the field
        (``info.trust: ...``), a ``tidy`` entry that is not a mapping is dropped (the planner then uses
        its default cost of a move), damaged caveats raise ``ValueError`` (``info.caveats: ...``)."""
        parsed = ("extra", "trust", "tidy", "caveats")
        known = {f.name for f in fields(cls)} - set(parsed)
        kw: dict[str, Any] = {k: v for k, v in d.items() if k in known}
        if "trust" in d:
            try:
                kw["trust"] = TrustReference.from_dict(d["trust"])
            except ValueError as e:
                raise ValueError(f"info.trust: {e}") from None
        if isinstance(d.get("tidy"), dict):
            kw["tidy"] = TidyCalibration.from_dict(d["tidy"])
        if d.get("caveats") is not None:
            try:
                kw["caveats"] = Caveats.from_dict(d["caveats"])
            except ValueError as e:
                raise ValueError(f"info.caveats: {e}") from None
        extra = {k: v for k, v in d.items() if k not in known and k not in parsed}
        return cls(**kw, extra=extra)
