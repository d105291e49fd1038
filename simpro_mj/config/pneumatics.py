"""``actuator.pneumatics``: the plant's typed block, where the scenario reaches it.

:class:`simpro_mj.plant.pneumatics.params.Pneumatics` defines the block (defaults,
units, ranges and rules across its keys); import it from there.
"""

from simpro_mj.plant.pneumatics.params import Pneumatics  # noqa: F401
