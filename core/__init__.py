"""vmt core: the identification side of the virtual machine-tool testbed.

Reads probe logs (``core.probelog``), speaks the ISO 230-1 / 230-7 error
vocabulary (``core.iso``), fits features, identifies machine and workpiece
errors, propagates uncertainty and discovers what a model misses.

Units inside ``core`` are SI (metres, radians, seconds); files carry the
probe-log units (mm, degrees) and reports name their units (``u95_um``).
``core`` imports numpy and scipy only: never sim, hardware, viz, mujoco or
rerun.
"""

__version__ = "0.1.0"
