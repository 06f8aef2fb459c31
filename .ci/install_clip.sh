#!/usr/bin/env bash
# Install the CLIP extra (open_clip) into a venv that already has the CPU torch 2.13.0, without pulling a
# CUDA torch. Usage: bash .ci/install_clip.sh /path/to/venv/bin/python
#
# torchvision 0.28.0 is the release built for torch 2.13.0 and pins torch==2.13.0, which the installed
# 2.13.0+cpu satisfies, so pip keeps the CPU torch. Its wheel is a CUDA build whose compiled ops cannot
# load with a CPU torch; scenescore.encoders.clip.import_open_clip works around the import error that
# causes (CLIP uses none of those ops). The last line checks that torch is still the CPU build and that
# open_clip and torchvision's transforms import and run.
set -euo pipefail
PY="${1:-python}"
"$PY" -m pip install --disable-pip-version-check -q "open-clip-torch==3.3.0" "torchvision==0.28.0"
"$PY" - <<'PYEOF'
import torch
assert torch.__version__.startswith("2.13.0") and torch.version.cuda is None, f"torch changed: {torch.__version__}"
from scenescore.encoders.clip import import_open_clip
open_clip = import_open_clip()
import numpy as np
from PIL import Image
from torchvision import transforms
x = transforms.Compose([transforms.Resize(16), transforms.CenterCrop(16), transforms.ToTensor()])(
    Image.fromarray(np.zeros((20, 30, 3), np.uint8)))
assert tuple(x.shape) == (3, 16, 16)
print(f"clip extra ok: open_clip {open_clip.__version__}, torch {torch.__version__} (CPU)")
PYEOF
