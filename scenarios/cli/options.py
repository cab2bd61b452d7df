"""Options shared by several ``vmt`` commands: one meaning per option name.

``--grid-mm`` (``identify``, ``design``) and the probing settings
(``probe``, ``machine program``) are parsed here, so the commands that take
them agree.
"""

from __future__ import annotations


def parse_grid(text: str, p_R):
    """``--grid-mm STEP`` (nodes at multiples of STEP covering ``p_R``) or ``x0:x1:step`` (both axes).

    ``p_R`` : (n, 2+) float, the nominal tip centres in R, m (used for STEP only).
    """
    from core.exceptions import ConfigError
    from core.selfcal import Grid
    from core.units import MM

    try:
        parts = [float(v) * MM for v in text.split(":")]
    except ValueError:
        raise ConfigError(f"--grid-mm: expected STEP or x0:x1:step in mm, got {text!r}") from None
    if len(parts) == 1:
        return Grid.from_extent(p_R, parts[0])
    if len(parts) == 3:
        return Grid.regular(parts[0], parts[1], parts[2])
    raise ConfigError(f"--grid-mm: expected STEP or x0:x1:step in mm, got {text!r}")


def add_settings_args(p, *, live: bool = True) -> None:
    """The probing settings shared by ``vmt probe`` and ``vmt machine program``."""
    p.add_argument("--plan", required=True, help="probe-log/1 plan (measured columns empty)")
    p.add_argument("--limits", help="soft limits, machine frame, mm: X-10:300,Y0:200,Z-100:0 "
                   "(required before any motion)")
    p.add_argument("--feed", type=float, default=100.0, help="probing feed, mm/min (100)")
    p.add_argument("--move-feed", type=float, default=1000.0, help="positioning feed, mm/min (1000)")
    p.add_argument("--max-feed", type=float, default=2000.0, help="no feed above this, mm/min (2000)")
    p.add_argument("--clearance", type=float, default=2.0, help="approach start before contact, mm (2)")
    p.add_argument("--overtravel", type=float, default=2.0, help="probing end beyond contact, mm (2)")
    p.add_argument("--safe-z", type=float, help="travel between touches at this machine Z, mm")
    if live:
        p.add_argument("--allow-miss", action="store_true",
                       help="probe with G38.3: a miss is logged no_trigger and the campaign goes on")


def settings_from_args(args):
    """The :class:`hardware.campaign.ProbeSettings` of the options :func:`add_settings_args` added."""
    from hardware.campaign import ProbeSettings, parse_limits

    return ProbeSettings(
        probe_feed_mm_min=args.feed, move_feed_mm_min=args.move_feed,
        max_feed_mm_min=args.max_feed, clearance_mm=args.clearance,
        overtravel_mm=args.overtravel, safe_z_mm=args.safe_z,
        allow_miss=bool(getattr(args, "allow_miss", False)),
        limits_mm=parse_limits(args.limits) if args.limits else None)
