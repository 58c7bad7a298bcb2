"""The structure kinds (METHOD.md section 1), one class each behind the :class:`Structure`
protocol.

The rig parser picks the class from ``structure.kind`` (:data:`KINDS`); every other module
asks the structure, never its kind. A new kind (a ring, a shaft) is one new module here and
one entry in :data:`KINDS`.
"""

from .base import UP, LumpedMass, Structure, locations
from .beam import Beam
from .body import Body
from .plate import Plate

KINDS: dict[str, type[Structure]] = {cls.kind: cls for cls in (Beam, Plate, Body)}
"""The rig file's ``structure.kind`` -> the class that reads and answers for it."""

__all__ = [
    "KINDS",
    "UP",
    "Beam",
    "Body",
    "LumpedMass",
    "Plate",
    "Structure",
    "locations",
]
