"""Parks at every level of the network: skylineEngine §4, Ulmer et al. §3.2.

"Procedurally, all these parks can be treated with a single park module, but
used at very different levels [of the pipeline]: large parks should be called
directly from the district design phase, while smaller ones should be
instantiated at the block or at the lot levels.  This clearly breaks the
linear pipeline model ... generating a simple Directed Acyclic Graph."  One
family of nodes, one ``parks`` stream running beside the city stream:

=================  ============================================  =========================
node               what becomes a park                            module
=================  ============================================  =========================
``parks.district`` the land-use map's park class (Central Park)   :mod:`.district`
``parks.block``    chosen blocks, before they are cut into lots   :mod:`.block`
``parks.lot``      chosen lots, which then get no building        :mod:`.lot`
``parks.patio``    a block's open core once buildings stand       :mod:`.patio`
=================  ============================================  =========================

Every park feature carries its ``level`` (``district``, ``block``, ``lot``,
``patio``).  Each node passes the parks made upstream through, so one
stream reaches the vegetation and the exporter; a node whose ``mode`` is
``none`` makes no park and hands its city layer on untouched: the
configuration decides at which levels parks are made.
"""

from .block import ParksBlock, choose_park_blocks, park_zones
from .district import ParksDistrict
from .lot import ParksLot, choose_park_lots
from .patio import ParksPatio, patio_zones

__all__ = [
    "choose_park_blocks",
    "choose_park_lots",
    "park_zones",
    "patio_zones",
    "ParksDistrict",
    "ParksBlock",
    "ParksLot",
    "ParksPatio",
]
