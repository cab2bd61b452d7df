"""Named studies composing sim, core, hardware and viz; home of the ``vmt`` CLI."""
