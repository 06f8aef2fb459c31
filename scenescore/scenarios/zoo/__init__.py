"""A zoo of seeded arrangement processes for robustness testing, each with an oracle.

Each scenario is one module here (``pcb.py`` ... ``hall.py``): a dataclass on
:class:`~scenescore.scenarios.zoo.common.ZooScenario` with ``name``, ``n_train``, ``n_test``, a
``bounds`` property, ``generate(n, seed)``, ``split(seed)``, ``missing`` (the categories an experiment
removes and asks a method to place back: never fixed, always present in a scene), ``symmetric``
(categories whose orientation means nothing: disks and squares), ``counts`` (the fewest and most
objects in a scene) and ``oracle(scene, name)``: the process's best guess for ``name`` from every
*other* object's pose (it never reads the named object's pose, only its size), so that its error is
the process noise. :data:`SCENARIOS` below is the one table of them by name, which the registry
(:func:`scenescore.scenarios.get`), the zoo experiment and the benchmarks read; a new scenario is a
module here and one line in it.

Together they span object sizes from 1 cm (a resistor) to 3 m (a banquet table), bounds from 0.3 m
across (a circuit board) to 16 m (a cafe), 2 to 80 objects a scene, fixed furniture,
multi-modal relations (which side, which end, which hand), chains of dependence, rows and grids of a
variable count, symmetric footprints and relations that depend on the objects' sizes:

========================  ====================================================================
``zoo-pcb``               resistors in a row (2-8) beside a fixed chip, on one of its 4 sides
``zoo-jars``              a grid of 2x2 .. 4x5 jars on a shelf; the pitch grows with the jar
``zoo-bedroom``           fixed bed; nightstand(s) either side of its head; a lamp beside each
``zoo-banquet``           fixed 3 m table in a 10 m hall; 4-12 chairs around it; a fixed sideboard
``zoo-workstation``       fixed monitor -> keyboard -> mouse on the right or left, mug opposite
``zoo-garden``            pots in a row from a fixed bench, largest first, gaps scale with the pots
``zoo-cascade``           crate -> case -> tin -> matchbox, each beside the last, turning one way
``zoo-books``             4-24 books sorted by depth from a fixed bookend, backs flush to the wall
``zoo-lounge``            fixed 2 m sofa in a 4.4 m room; coffee table, side table at one end
``zoo-hall``              fixed 2 m console anywhere in a 4.4 m hall; vases at its ends, a stool
``zoo-classroom``         14-22 fixed desks on a grid in a 12 x 10 m room, a chair behind each
``zoo-cafe``              8-16 fixed tables in a 16 x 12 m room, turned by quarter turns, 4 chairs each
========================  ====================================================================

The last two are rooms (:data:`ROOMS`: 28 to 80 objects): their ``missing_count`` is 3, the number of
interchangeable chairs the zoo experiment removes from each test scene at once, and their
``oracle_many(scene, names)`` returns the free slots (every scenario has it: by default each object's
``oracle``); the experiment matches placements and the oracle's poses to the truths by assignment.

Poses carry clipped Gaussian noise (about 1-3 % of the relation's length scale). Scenes are drawn
again (from the same stream, so still reproducible) until every object lies inside the bounds and no
two footprints overlap.
"""

from __future__ import annotations

from .banquet import BanquetScenario
from .bedroom import BedroomScenario
from .books import BookshelfScenario
from .cafe import CafeScenario
from .cascade import CascadeScenario
from .classroom import ClassroomScenario
from .common import ZooScenario
from .garden import GardenScenario
from .hall import HallScenario
from .jars import JarGridScenario
from .lounge import LoungeScenario
from .pcb import PcbScenario
from .workstation import WorkstationScenario

__all__ = [
    "ZOO",
    "ROOMS",
    "SCENARIOS",
    "ZooScenario",
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
]

# every zoo scenario by its name (each class's ``name``), in the order experiments and reports list them
SCENARIOS: dict[str, type[ZooScenario]] = {
    cls.name: cls
    for cls in (
        PcbScenario,
        JarGridScenario,
        BedroomScenario,
        BanquetScenario,
        WorkstationScenario,
        GardenScenario,
        CascadeScenario,
        BookshelfScenario,
        LoungeScenario,
        HallScenario,
        ClassroomScenario,
        CafeScenario,
    )
}
ZOO: tuple[str, ...] = tuple(SCENARIOS)  # the zoo's scenario names
# the room-scale scenarios: 28 to 80 objects, several chairs missing at once
ROOMS: tuple[str, ...] = tuple(name for name, cls in SCENARIOS.items() if cls.missing_count > 1)
