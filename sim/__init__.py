"""The virtual machine: exact Pinocchio chain with injected errors, artefacts,
MuJoCo scene and touch-trigger simulation. Units: SI (m, rad, s)."""
