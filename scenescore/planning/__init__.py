"""Planning with a trained model: where objects go, and how to get a messy scene there.

- ``placement.py``: :func:`place`, the unknown poses of a scene filled by the learned energy (with
  non-overlap), solved by the ``langevin`` solver;
- ``heatmap.py``: the learned energy over one object's position, the rest fixed;
- ``tidying/``: :func:`tidy`, which objects of a messy scene to move, where, and in what order.
"""

from .heatmap import energy_grid
from .placement import place, place_many
from .tidying import tidy

__all__ = ["energy_grid", "place", "place_many", "tidy"]
