"""Adapters for real machines (GRBL live, LinuxCNC offline) and the emulator."""
