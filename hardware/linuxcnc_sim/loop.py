"""LinuxCNC in the loop: a part program run by real LinuxCNC against vmt's virtual machine.

:func:`run_program` copies the simulation config shipped in this folder
(``vmt_sim.ini``, ``vmt_sim.hal``, ``vmt_display.py``, ``vmt_probe.py``)
to a scratch directory, starts a :class:`ContactServer` that puts a
virtual machine (anything with ``probe_move(start_m, target_m, rot_rad)``:
:class:`hardware.scene.SimpleScene`, ``sim.probe.VirtualMachine``) behind a
local TCP socket, and runs ``linuxcnc vmt_sim.ini`` headless. LinuxCNC's
display program homes, runs the part program in AUTO and exits; its
userspace component ``vmtprobe`` asks the contact server where each probing
move meets the part, and HAL trips the probe input in the servo thread.

``run_program(..., config="vmt_rotary.ini", comp_files={"C": path})`` runs
the second configuration instead: an X Y Z A C machine without the probe
chain, each given joint loading its compensation file through LinuxCNC's
own ``[JOINT_n] COMP_FILE``; its userspace component ``vmtjoints`` records,
at every stop, each joint's command and the motor command LinuxCNC makes of
it (:attr:`LoopResult.joint_log`).

Resolution: LinuxCNC latches the first servo sample past the trigger
point, so a touch in the probe file lies on the probing line between the
virtual machine's trigger point and one servo period of travel beyond it:
``0 <= e <= F * T`` (probe feed ``F``, servo period ``T`` = 1 ms;
30 mm/min gives 0.5 um), plus the file's 6 decimals (0.5 nm).

LinuxCNC refuses to run as root: when this process is root the run is made
as an unprivileged user (created if missing, ``useradd``), and the scratch
directory is given to that user. Everything LinuxCNC needs is in the scratch
directory; vmt's own files are read by this process only.
"""

from __future__ import annotations

import json
import os
import pwd
import shutil
import socket
import subprocess
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from core.exceptions import ConfigError, HardwareError

HERE = Path(__file__).resolve().parent
CONFIG_FILES = ("vmt_sim.ini", "vmt_sim.hal", "vmt_sim.tbl", "vmt_display.py", "vmt_probe.py",
                "vmt_rotary.ini", "vmt_rotary.hal", "vmt_joints.py")
#: The configurations shipped here: a 3-axis mill with the probe chain, and an X Y Z A C machine
#: recording every joint's command and motor command at each stop (vmt_joints.py), no probe.
CONFIGS = ("vmt_sim.ini", "vmt_rotary.ini")
#: Servo period of ``vmt_sim.ini``, s.
SERVO_PERIOD_S = 1e-3
#: Length of the ray the contact server follows from a probing move's first point, mm.
RAY_MM = 100.0
DEFAULT_USER = "vmtcnc"


def resolution_mm(probe_feed_mm_min: float) -> float:
    """Largest distance (mm) between a probe-file touch and the true trigger: ``F * T``."""
    return probe_feed_mm_min / 60.0 * SERVO_PERIOD_S


class ContactServer:
    """The virtual machine behind a local socket, answering ``vmtprobe``'s questions.

    One client; one line a question: ``probe x y z dx dy dz`` (mm, machine
    frame) -> ``hit qx qy qz`` (axis positions at the trigger, mm) or ``miss``.
    Every answer is kept in :attr:`answers` (dicts with ``p1_mm``, ``d``,
    ``q_mm`` or ``None``).
    """

    def __init__(self, machine, host: str = "127.0.0.1"):
        if not callable(getattr(machine, "probe_move", None)):
            raise ConfigError(f"contact server: {type(machine).__name__} has no probe_move method")
        self.machine = machine
        self.answers: list[dict] = []
        self.error: str | None = None
        self._sock = socket.create_server((host, 0))
        self._sock.settimeout(0.2)
        self.address = "%s:%d" % self._sock.getsockname()[:2]
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)

    def start(self) -> "ContactServer":
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(5)
        self._sock.close()

    def _serve(self) -> None:
        conn = None
        while not self._stop.is_set() and conn is None:
            try:
                conn, _ = self._sock.accept()
            except socket.timeout:
                continue
        if conn is None:
            return
        conn.settimeout(0.2)
        buf = b""
        with conn:
            while not self._stop.is_set():
                try:
                    chunk = conn.recv(4096)
                except socket.timeout:
                    continue
                if not chunk:
                    return
                buf += chunk
                while b"\n" in buf:
                    line, buf = buf.split(b"\n", 1)
                    conn.sendall((self._answer(line.decode("ascii", "replace")) + "\n").encode())

    def _answer(self, line: str) -> str:
        parts = line.split()
        try:
            if len(parts) != 7 or parts[0] != "probe":
                raise ValueError(line[:60])
            v = np.array([float(x) for x in parts[1:]])
            p1, d = v[:3], v[3:] / np.linalg.norm(v[3:])
            hit, q_m = self.machine.probe_move(p1 * 1e-3, (p1 + RAY_MM * d) * 1e-3, np.zeros(3))
        except Exception as e:  # a bad question must not kill the server: say miss, keep the reason
            self.error = f"contact server: {type(e).__name__}: {e}"
            return "miss"
        q = np.asarray(q_m, float).reshape(3) * 1e3 if hit else None
        self.answers.append({"p1_mm": p1, "d": d, "q_mm": q})
        return "miss" if q is None else "hit %.12f %.12f %.12f" % tuple(q)


@dataclass(frozen=True)
class LoopResult:
    """What one LinuxCNC run produced.

    Attributes
    ----------
    ok : bool
        The program ran to its end without an error message.
    probe_file : Path or None
        The probe file LinuxCNC wrote (copied out of the scratch directory).
    errors, messages : list of str
        LinuxCNC's error channel.
    homed_s, run_s, total_s : float
        Seconds from the display's start to all joints homed, of the program
        run in AUTO, and of the display's whole life.
    wall_s : float
        Seconds from launching ``linuxcnc`` to its exit.
    answers : list of dict
        The contact server's answers, in order.
    component_log : list of dict
        ``vmtprobe``'s own record of each probing move (``late`` must be False).
    joint_log : list of dict
        ``vmtjoints``' record of every stop (``vmt_rotary.ini``): ``pos_cmd``,
        ``motor_pos_cmd``, ``motor_offset``, one value per joint.
    parameters : dict[int, float]
        LinuxCNC's parameter file after the run.
    output : str
        LinuxCNC's stdout and stderr.
    """

    ok: bool
    probe_file: Path | None
    errors: list
    messages: list
    homed_s: float
    run_s: float
    total_s: float
    wall_s: float
    answers: list = field(default_factory=list)
    component_log: list = field(default_factory=list)
    joint_log: list = field(default_factory=list)
    parameters: dict = field(default_factory=dict)
    output: str = ""


def linuxcnc_path() -> str:
    """The ``linuxcnc`` launcher, or a :class:`HardwareError` saying how to install it."""
    p = shutil.which("linuxcnc")
    if p is None:
        raise HardwareError("linuxcnc not found: install Debian's linuxcnc-uspace "
                            "(apt-get install -y linuxcnc-uspace; make test-controllers does)")
    return p


def ensure_user(name: str = DEFAULT_USER) -> pwd.struct_passwd:
    """The unprivileged user LinuxCNC runs as, created (``useradd``) if missing (needs root)."""
    try:
        return pwd.getpwnam(name)
    except KeyError:
        pass
    r = subprocess.run(["useradd", "--create-home", "--shell", "/bin/sh", name],
                       capture_output=True, text=True)
    if r.returncode != 0:
        raise HardwareError(f"useradd {name}: {r.stderr.strip() or r.returncode}")
    return pwd.getpwnam(name)


def write_parameters(path: Path, params: dict) -> None:
    """A LinuxCNC parameter file (``number<TAB>value`` lines, ascending)."""
    path.write_text("".join(f"{k}\t{float(v):.6f}\n" for k, v in sorted(params.items())))


def read_parameters(path: Path) -> dict:
    out = {}
    if path.is_file():
        for line in path.read_text().splitlines():
            parts = line.split()
            if len(parts) == 2:
                try:
                    out[int(parts[0])] = float(parts[1])
                except ValueError:
                    continue
    return out


def _read_jsonl(path: Path) -> list:
    if not path.is_file():
        return []
    return [json.loads(ln) for ln in path.read_text().splitlines() if ln.strip()]


def _add_to_ini(ini: Path, comp_files: dict, wrapped: tuple = ()) -> None:
    """Give the joints of ``comp_files`` (axis letter -> file in the scratch directory) their
    ``COMP_FILE`` and ``COMP_FILE_TYPE = 0`` (trivkins: joint j is the j-th letter of ``[TRAJ] COORDINATES``),
    and each axis of ``wrapped`` ``WRAPPED_ROTARY = 1`` in its ``[AXIS_<letter>]``."""
    lines = ini.read_text().splitlines()
    coords = next((ln.split("=", 1)[1].split() for ln in lines if ln.replace(" ", "").startswith("COORDINATES=")), [])
    adds = [(f"[JOINT_{coords.index(a)}]" if a in coords else None, a, [f"COMP_FILE = {name}", "COMP_FILE_TYPE = 0"])
            for a, name in comp_files.items()]
    adds += [(f"[AXIS_{a}]" if a in coords else None, a, ["WRAPPED_ROTARY = 1"]) for a in wrapped]
    for head, axis, new in adds:
        if head is None:
            raise ConfigError(f"{ini.name}: no axis {axis!r} in COORDINATES {' '.join(coords)}")
        if head not in lines:
            raise ConfigError(f"{ini.name}: no section {head} for axis {axis}")
        k = lines.index(head)
        lines[k + 1:k + 1] = new
    ini.write_text("\n".join(lines) + "\n")


def run_program(program, machine=None, *, probe_file: str | None = None, out_dir, parameters: dict | None = None,
                user: str = DEFAULT_USER, timeout_s: float = 900.0, config: str = "vmt_sim.ini",
                comp_files: dict | None = None, wrapped_rotary: tuple = ()) -> LoopResult:
    """Run a part program on LinuxCNC (simulation config of this folder) against ``machine``.

    Parameters
    ----------
    program : path-like
        The part program (``vmt machine program``).
    machine : object with ``probe_move(start_m, target_m, rot_rad)``, or None
        The virtual machine and part (machine frame R, m); None: nothing answers
        a probing move (a configuration without the probe chain, ``vmt_rotary.ini``).
    probe_file : str or None
        The file named in the program's ``(LOGOPEN,...)``; a relative name is
        relative to the config directory, where LinuxCNC runs.
    out_dir : path-like
        Where the probe file and LinuxCNC's output are copied.
    parameters : dict[int, float] or None
        Initial parameter file (e.g. a G59.3 with a rotation, G92 offsets).
    user : str
        Unprivileged user to run as when this process is root.
    timeout_s : float
        The whole run is killed after this long (``HardwareError``).
    config : str
        The INI file of this folder to run (:data:`CONFIGS`).
    comp_files : dict or None
        Axis letter -> a LinuxCNC compensation file (TYPE 0) to load for that
        axis's joint: copied as ``<axis>.comp`` and named in its ``[JOINT_n]``
        (``COMP_FILE``, ``COMP_FILE_TYPE = 0``), so LinuxCNC's own loader
        (``usrmotLoadComp()``) reads it at start-up.
    wrapped_rotary : tuple of str
        Rotary axes made ``WRAPPED_ROTARY = 1`` (``[AXIS_<letter>]``): the
        interpreter takes ``C10`` after ``C350`` the short way, to joint
        position 370 (``unwrap_rotary()``, rs274ngc).

    Raises
    ------
    HardwareError
        LinuxCNC missing, the user cannot be made, LinuxCNC did not finish in time.
    """
    exe = linuxcnc_path()
    if config not in CONFIGS:
        raise ConfigError(f"run_program: config must be one of {', '.join(CONFIGS)}, got {config!r}")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix="vmt-linuxcnc-"))
    os.chmod(work, 0o755)
    for f in CONFIG_FILES:
        shutil.copy2(HERE / f, work / f)
    for f in ("vmt_display.py", "vmt_probe.py", "vmt_joints.py"):
        os.chmod(work / f, 0o755)
    shutil.copy2(program, work / "program.ngc")
    for axis, src in (comp_files or {}).items():
        shutil.copy2(src, work / f"{axis}.comp")
    if comp_files or wrapped_rotary:
        _add_to_ini(work / config, {a: f"{a}.comp" for a in comp_files or {}}, tuple(wrapped_rotary))
    write_parameters(work / "vmt_sim.var", parameters or {})
    env = {"PATH": "/usr/local/bin:/usr/bin:/bin:/usr/sbin:/sbin", "LANG": "C.UTF-8",
           "VMT_PROGRAM": str(work / "program.ngc"), "VMT_RESULT": str(work / "result.json"),
           "VMT_PROBE_LOG": str(work / "vmtprobe.jsonl"), "VMT_JOINT_LOG": str(work / "vmtjoints.jsonl"),
           "VMT_TIMEOUT_S": str(timeout_s)}
    cmd = [exe, str(work / config)]
    if os.geteuid() == 0:
        pw = ensure_user(user)
        for p in [work, *work.iterdir()]:
            os.chown(p, pw.pw_uid, pw.pw_gid)
        env.update(HOME=pw.pw_dir, USER=pw.pw_name, LOGNAME=pw.pw_name)
        cmd = ["runuser", "-u", pw.pw_name, "--"] + cmd
    else:
        env.update(HOME=os.environ.get("HOME", str(work)))
    server = None if machine is None else ContactServer(machine).start()
    if server is not None:
        env["VMT_CONTACT"] = server.address
    t0 = time.monotonic()
    try:
        proc = subprocess.Popen(cmd, cwd=work, env=env, stdin=subprocess.DEVNULL,
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                start_new_session=True)
        try:
            output, _ = proc.communicate(timeout=timeout_s + 60)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, 9)
            output, _ = proc.communicate()
            (out_dir / "linuxcnc.out").write_text(output)
            raise HardwareError(f"LinuxCNC did not finish within {timeout_s + 60:g} s "
                                f"(output in {out_dir / 'linuxcnc.out'})") from None
    finally:
        if server is not None:
            server.stop()
    wall = time.monotonic() - t0
    for f in ("linuxcnc_print.txt", "linuxcnc_debug.txt"):    # the launcher's own logs, in HOME
        fp = Path(env["HOME"]) / f
        if fp.is_file():
            output += f"\n--- {f}\n" + fp.read_text(errors="replace")
    (out_dir / "linuxcnc.out").write_text(output)
    res = json.loads((work / "result.json").read_text()) if (work / "result.json").is_file() else {
        "ok": False, "errors": ["the display program wrote no result (see linuxcnc.out)"], "messages": []}
    if server is not None and server.error:
        res["errors"].append(server.error)
        res["ok"] = False
    copied = None
    pf = None if probe_file is None else Path(probe_file)
    pf = pf if pf is None or pf.is_absolute() else work / pf
    if pf is not None and pf.is_file():
        copied = out_dir / pf.name
        shutil.copy2(pf, copied)
    result = LoopResult(ok=bool(res["ok"]), probe_file=copied, errors=list(res["errors"]),
                        messages=list(res["messages"]), homed_s=float(res.get("homed_s", float("nan"))),
                        run_s=float(res.get("run_s", float("nan"))),
                        total_s=float(res.get("total_s", float("nan"))), wall_s=wall,
                        answers=[] if server is None else server.answers,
                        component_log=_read_jsonl(work / "vmtprobe.jsonl"),
                        joint_log=_read_jsonl(work / "vmtjoints.jsonl"),
                        parameters=read_parameters(work / "vmt_sim.var"), output=output)
    shutil.rmtree(work, ignore_errors=True)
    return result
