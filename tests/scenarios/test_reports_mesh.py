"""The demo recording's artefact mesh: the expected absences fall back, a fault raises (review31d F7)."""

from types import SimpleNamespace

import numpy as np
import pytest
import trimesh

from scenarios import reports


class _Record:
    """A stand-in for viz.record: keeps what would be logged."""

    TABLE, PROBE, SPINDLE, ARTEFACT = "table", "probe", "spindle", "artefact"

    def __init__(self):
        self.meshes = {}

    def log_mesh(self, rec, path, vertices, faces, **kw):
        self.meshes[path] = np.asarray(vertices)

    def log_probe_path(self, rec, p):
        pass


def _touches():
    return SimpleNamespace(pn_R=np.array([[0.0, 0.0, 0.100], [0.01, 0.0, 0.120]]))


def _table_top(record):
    return float(record.meshes["table"][:, 2].max())


def test_no_artefact_falls_back_to_below_the_touches():
    rec = _Record()
    reports._log_machine_bodies(None, rec, _touches(), art=None)
    assert _table_top(rec) == pytest.approx(0.100 - 0.013, abs=1e-12)  # 13 mm below the lowest touch
    empty = SimpleNamespace(mesh=lambda: trimesh.Trimesh(), T_W_A=np.eye(4))  # an artefact without solids
    assert reports._artefact_mesh(empty) is None
    assert reports._artefact_mesh(SimpleNamespace()) is None  # no mesh method


def test_the_artefact_sets_the_table_top():
    box = trimesh.creation.box(extents=(0.1, 0.1, 0.02))  # its lowest face at z = -0.01 in A
    T = np.eye(4)
    T[2, 3] = 0.05  # placed 50 mm up in W: lowest point 0.04
    rec = _Record()
    reports._log_machine_bodies(None, rec, _touches(), art=SimpleNamespace(mesh=lambda: box, T_W_A=T))
    assert _table_top(rec) == pytest.approx(0.04, abs=1e-12)


def test_a_fault_in_the_artefacts_mesh_raises():
    """Before, ``except Exception: pass`` took a programming error for "no mesh" and drew the fallback."""
    def broken():
        raise TypeError("a bug in the mesh code")

    with pytest.raises(TypeError, match="a bug"):
        reports._log_machine_bodies(None, _Record(), _touches(), art=SimpleNamespace(mesh=broken, T_W_A=np.eye(4)))
    with pytest.raises(TypeError, match="a bug"):
        reports._artefact_mesh(SimpleNamespace(mesh=broken))
