"""Units: multiply a value in the named unit by its constant to get SI.

``x_m = x_mm * MM``, ``u_m = u_um * UM``, ``a_rad = a_deg * DEG``,
``e_rad = e_urad * URAD``; divide to go back (``x_m / MM`` is in mm).
Inside the code everything is SI (m, rad, s); the shop units appear only in
names (``x_mm``, ``u95_um``), at file and report boundaries.
"""

from __future__ import annotations

import math

#: One millimetre in metres.
MM = 1e-3
#: One micrometre in metres.
UM = 1e-6
#: One degree in radians.
DEG = math.pi / 180.0
#: One microradian in radians.
URAD = 1e-6
