"""rerun recordings and static report figures. Draws results; computes nothing."""
