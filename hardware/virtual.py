"""The virtual machine behind the hardware interface, and the backend opener.

The one hardware module (besides the GRBL emulator) that may import the
simulator: :class:`SimMachine` adapts ``sim.probe.VirtualMachine`` to the
``probe_move`` duck type the emulator and :class:`hardware.backend.VirtualBackend`
use, :func:`sim_machine` builds it for a named artefact, :func:`builtin_machine`
is the small known-error scene (:class:`hardware.scene.SimpleScene`), and
:func:`open_backend` turns a ``--controller`` URL into a probing backend.
"""

from __future__ import annotations

import numpy as np

from core.exceptions import ConfigError, HardwareError
from core.units import UM

#: URLs naming the built-in scene (``virtual:``).
BUILTIN_URLS = ("virtual:", "virtual://", "virtual://builtin")


def builtin_machine(noise_um: float = 0.0, seed: int = 0, scale_ppm=(0.0, 0.0, 0.0),
                    ec0y_urad: float = 0.0):
    """The small scene ``vmt machine serve --scene simple`` and ``virtual:`` use.

    A table top at Z = 0 and a sphere of radius 12.5 mm at (50, 50, 0) mm
    (stylus-tip-centre space), linear scale errors (``scale_ppm``, um/m) and
    a squareness ``ec0y_urad``, all known; ``noise_um`` the probing noise, a
    standard deviation (k = 1) along the approach, um.
    """
    from core.units import URAD

    from .scene import SimpleScene

    return SimpleScene(scale=tuple(s * UM for s in scale_ppm), ec0y_rad=ec0y_urad * URAD,
                       noise_m=noise_um * UM, rng=np.random.default_rng(seed))


class SimMachine:
    """The simulator's virtual machine behind the emulator's ``probe_move``.

    The emulator speaks rotary positions as (A, B, C); the simulated
    machine takes only its own rotary axes, in its own order.
    """

    def __init__(self, vm):
        self.vm = vm
        self.rotary_axes = tuple(getattr(vm.machine, "rotary_axes", ()) or ())

    def probe_move(self, start_m, target_m, rot_rad=None):
        """Probe from ``start_m`` towards ``target_m`` (m, R) at rotary ``rot_rad`` (A, B, C rad)."""
        rot = None
        if self.rotary_axes:
            abc = np.zeros(3) if rot_rad is None else np.asarray(rot_rad, float).reshape(-1)
            abc = np.pad(abc, (0, max(0, 3 - abc.size)))[:3]
            rot = np.array([abc["ABC".index(a)] for a in self.rotary_axes])
        return self.vm.probe_move(start_m, target_m, rot)


def sim_machine(scene: str = "cross-pocket", noise_um: float | None = 0.0, seed: int = 0,
                spec=None) -> SimMachine:
    """The simulator's virtual machine with artefact ``scene`` on the table.

    ``spec`` (a :class:`sim.machinefile.MachineSpec`, ``--machine NAME|FILE``)
    is the machine and probe; default the nmv3000 as ``machine serve
    --scene`` names it (:func:`sim.machinefile.truth_machine`, error set
    ``"drawn"``), so ``virtual:SCENE`` and the emulator are one machine.
    ``noise_um`` is the probing standard deviation (k=1) along the approach,
    um (None: the spec's probe).

    Raises
    ------
    ConfigError
        ``scene`` is no artefact of :data:`sim.catalog.CATALOG`.
    """
    from dataclasses import replace

    from sim.catalog import CATALOG, make_artefact
    from sim.machine import Machine
    from sim.machinefile import truth_machine
    from sim.probe import VirtualMachine

    if scene not in CATALOG:
        raise ConfigError(f"--scene {scene!r}: expected simple or one of {', '.join(sorted(CATALOG))}")
    if spec is None:
        spec = truth_machine("nmv3000", default="drawn")
    m = Machine(spec.config)
    probe = spec.probe
    if noise_um is not None:
        probe = replace(probe, repeatability_k2_m=2 * noise_um * UM)
    vm = VirtualMachine(m, make_artefact(scene), probe, np.random.default_rng(seed))
    return SimMachine(vm)


def open_backend(url: str, *, timeout_s: float = 60.0, rotary: bool = False, on_event=None,
                 transcript=None, axes: str | None = None, reset: bool = False):
    """A probing backend for a ``--controller`` URL.

    ``grbl://HOST:PORT``, ``tcp://...`` or ``serial:///dev/ttyX`` connect to a
    GRBL controller (:func:`hardware.grbl.connect`, with ``timeout_s``,
    ``rotary``, ``on_event``, ``transcript``, the controller's ``axes`` when
    the user names them, ``reset`` to send Ctrl-X first); ``virtual:`` is the
    built-in scene, ``virtual:SCENE`` the simulator with that artefact.

    Raises
    ------
    HardwareError
        An URL of none of these forms.
    """
    from .backend import VirtualBackend

    if url.startswith(("grbl://", "tcp://", "serial://")):
        from .grbl import connect

        return connect(url, timeout_s=timeout_s, on_event=on_event, transcript=transcript, rotary=rotary,
                       axes=axes, reset=reset)
    if url in BUILTIN_URLS:
        return VirtualBackend(builtin_machine(), name="virtual:builtin")
    if url.startswith("virtual:") and url[len("virtual:"):].lstrip("/"):
        scene = url[len("virtual:"):].lstrip("/")
        from sim.catalog import CATALOG

        if scene not in CATALOG:    # sim_machine's own words name machine serve's --scene (audit37)
            raise HardwareError(f"--controller {url!r}: no scene {scene!r}: expected virtual: (the built-in "
                                f"scene) or virtual:SCENE, SCENE one of {', '.join(sorted(CATALOG))}")
        return VirtualBackend(sim_machine(scene), name=f"virtual:{scene}")
    raise HardwareError(f"--controller {url!r}: expected grbl://HOST:PORT, serial:///dev/ttyX, virtual: "
                        "or virtual:SCENE (cross-pocket, pin-circle, freeform, mfb)")
