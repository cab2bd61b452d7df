"""A small stand-in machine for the emulator and the tests: known errors, exact geometry.

Until the simulator's ``sim.probe.VirtualMachine`` is wired in, ``vmt machine
serve`` puts this scene behind the GRBL protocol. It has the one method the
hardware package needs from a virtual machine (duck typing)::

    probe_move(start_m (3,), target_m (3,), rot_rad (3,)) -> (triggered, pos_m (3,))

Geometry is given in stylus-tip-centre space (surfaces already offset by the
stylus radius): a flat table top ``z = plane_z_m`` (material below) and solid
spheres. The machine's error is linear and known: where the controller
believes the tip is (``p_cmd``, machine frame R, m) the tip actually is at
``p_act = p_cmd + E @ p_cmd``, with ``E = diag(scale) + squareness`` (the
ISO 230-1 ``EXX``-like scale errors as slopes and ``EC0Y``: tip error
``-y * EC0Y`` in X, CONTRIBUTING). The reported position is ``p_cmd`` at the
trigger plus seeded Gaussian noise along the approach direction (a standard
deviation, k = 1, as ``--noise-um`` everywhere).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class SimpleScene:
    """Flat table and spheres on a machine with linear, known errors.

    Attributes
    ----------
    plane_z_m : float or None
        Height of the table top (tip-centre space), m; ``None``: no table.
    spheres : tuple of ((3,) tuple, float)
        ``(centre_R_m, radius_m)`` of solid spheres (tip-centre space).
    scale : (3,) tuple of float
        Scale error slopes of X, Y, Z (m/m): 10e-6 is 10 µm per metre.
    ec0y_rad : float
        Squareness of Y to X (rad).
    noise_m : float
        Standard deviation (k = 1) of the reported position along the
        approach direction, m.
    rng : numpy.random.Generator or None
        Source of the noise (required when ``noise_m > 0``).
    """

    plane_z_m: float | None = 0.0
    spheres: tuple = ((( 0.05, 0.05, 0.0), 0.0125),)
    scale: tuple = (0.0, 0.0, 0.0)
    ec0y_rad: float = 0.0
    noise_m: float = 0.0
    rng: np.random.Generator | None = field(default=None, compare=False)

    def __post_init__(self):
        from core.exceptions import ConfigError

        if self.noise_m < 0:
            raise ConfigError(f"SimpleScene: noise_m {self.noise_m!r} is negative")
        if self.noise_m > 0 and self.rng is None:
            raise ConfigError("SimpleScene: noise_m > 0 needs an rng")

    @property
    def E(self) -> np.ndarray:
        """(3, 3) linear error matrix: actual tip = ``(I + E) @ p_cmd``."""
        e = np.diag(np.asarray(self.scale, dtype=float))
        e[0, 1] = -self.ec0y_rad
        return e

    def in_contact(self, pos_m, rot_rad=(0.0, 0.0, 0.0)) -> bool:
        """Whether the stylus touches or is inside material at ``pos_m`` (commanded, R, m)."""
        pa = (np.eye(3) + self.E) @ np.asarray(pos_m, dtype=float).reshape(3)
        if self.plane_z_m is not None and pa[2] <= self.plane_z_m:
            return True
        return any(float(np.sum((pa - np.asarray(c, dtype=float)) ** 2)) <= r * r for c, r in self.spheres)

    def probe_move(self, start_m, target_m, rot_rad=(0.0, 0.0, 0.0)):
        """Move linearly from ``start_m`` towards ``target_m``; stop at the first contact.

        Parameters
        ----------
        start_m, target_m : (3,) float
            Commanded tip-centre positions, machine frame R, m.
        rot_rad : (3,) float
            Rotary axes (unused by this scene).

        Returns
        -------
        triggered : bool
        pos_m : (3,) float
            Reported (commanded-scale) position at the trigger, or ``target_m``
            when nothing was touched. A start already in contact triggers at once.
        """
        a = np.asarray(start_m, dtype=float)
        b = np.asarray(target_m, dtype=float)
        u = b - a
        M = np.eye(3) + self.E
        pa, pu = M @ a, M @ u          # actual tip: pa + s * pu, s in [0, 1]
        hits = []
        if self.plane_z_m is not None:
            if pa[2] <= self.plane_z_m:
                hits.append(0.0)
            elif pu[2] < 0:
                hits.append((self.plane_z_m - pa[2]) / pu[2])
        for c, r in self.spheres:
            d = pa - np.asarray(c, dtype=float)
            if d @ d <= r * r:
                hits.append(0.0)
                continue
            A, B, C = pu @ pu, 2 * d @ pu, d @ d - r * r
            disc = B * B - 4 * A * C
            if A > 0 and disc >= 0:
                s = (-B - np.sqrt(disc)) / (2 * A)
                if s >= 0:
                    hits.append(s)
        hits = [s for s in hits if s <= 1.0]
        if not hits:
            return False, b.copy()
        s0 = min(hits)
        if s0 == 0.0:                  # already in contact: trigger where it stands
            return True, a.copy()
        p = a + s0 * u
        if self.noise_m > 0:
            p = p + self.rng.normal(0.0, self.noise_m) * u / np.linalg.norm(u)
        return True, p
