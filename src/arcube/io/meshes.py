"""Triangle meshes of the anatomy (model §14.2): STL, OBJ and PLY in, binary STL out.

Each mesh is a set of closed surfaces, each bounding a forbidden solid, in millimetres.
:func:`read_mesh` returns it in the patient frame R_w (x = patient's right, y = superior,
z = posterior), converted like markups (:mod:`arcube.io.slicer`): a file point p becomes
``PATIENT_FROM_LPS @ p`` (``frame="LPS"``, 3D Slicer's default for saved models),
``PATIENT_FROM_RAS @ p`` (``frame="RAS"``) or p itself (``frame="patient"``, what
:func:`write_stl` writes by default). The frame is always given by the caller, never guessed.
When the file's header declares a coordinate system (3D Slicer writes ``SPACE=LPS`` or
``SPACE=RAS`` in the header comment of every mesh it saves; :func:`write_stl` writes
``frame=patient``, ``SPACE=LPS`` or ``SPACE=RAS``) and it contradicts the given frame, reading
fails rather than silently mirroring the anatomy.

A mesh is accepted when it is a regular file of at most 1 GiB, has at least one triangle, only
finite vertex coordinates within ±1e5 mm (:mod:`arcube.io.inputs`), and is
closed with consistent orientation: after merging coincident vertices, every directed edge
a→b is matched by an opposite edge b→a (so several closed shells in one file, even touching
ones, are fine), and every connected shell encloses a positive volume (faces oriented
outward; cavities are not supported). Every problem raises :class:`~arcube.errors.InputError`
with a one-line message naming the file.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np
import trimesh

from arcube import interrupts
from arcube.errors import InputError
from arcube.io.files import atomic_write_bytes
from arcube.io.inputs import COORDINATE_LIMIT_MM, MAX_MESH_BYTES, read_bytes
from arcube.io.slicer import PATIENT_FROM_LPS, PATIENT_FROM_RAS

interrupts.check()  # trimesh's optional imports (above) catch BaseException: a Ctrl-C there must not be lost

__all__ = ["FRAMES", "MESH_SUFFIXES", "read_mesh", "read_meshes", "split_shells", "write_stl"]

# frame name -> matrix taking file coordinates to the patient frame (all rotations, det +1).
_TO_PATIENT = {"LPS": PATIENT_FROM_LPS, "RAS": PATIENT_FROM_RAS, "patient": np.eye(3)}
FRAMES = tuple(_TO_PATIENT)
MESH_SUFFIXES = (".stl", ".obj", ".ply")
_HEADER_BYTES = 1024  # where header comments (SPACE=..., frame=...) are looked for


def _check_frame(frame: object, where: str) -> str:
    if not isinstance(frame, str) or frame not in _TO_PATIENT:
        raise InputError(f"{where}: unknown frame {frame!r} (expected LPS, RAS or patient)")
    return frame


def _declared_frame(head: bytes) -> str | None:
    """Coordinate system declared in a file's first bytes, or None (absent or ambiguous)."""
    text = head.decode("latin-1").upper().replace(" ", "")
    found = {
        name for name, tag in (("LPS", "SPACE=LPS"), ("RAS", "SPACE=RAS"), ("patient", "FRAME=PATIENT")) if tag in text
    }
    return found.pop() if len(found) == 1 else None


def _sniff_stl(path: Path, data: bytes) -> bool:
    """True for binary STL, False for ASCII STL; InputError for anything else (e.g. other text)."""
    if len(data) >= 84 and 84 + 50 * int.from_bytes(data[80:84], "little") == len(data):
        return True  # binary STL: the triangle count matches the size
    if data.lstrip()[:5].lower() == b"solid":
        return False
    raise InputError(f"{path}: not an STL file (neither binary STL nor ASCII 'solid ...')")


def _unmatched_edges(faces: np.ndarray) -> int:
    """Directed edges a→b without a matching b→a (0 for closed, consistently oriented shells)."""
    a = faces[:, [0, 1, 2]].reshape(-1).astype(np.int64)
    b = faces[:, [1, 2, 0]].reshape(-1).astype(np.int64)
    n = int(faces.max()) + 1
    fwd, rev = np.sort(a * n + b), np.sort(b * n + a)
    if np.array_equal(fwd, rev):
        return 0
    # multiset difference size, for the message
    keys, counts = np.unique(np.concatenate([fwd, rev]), return_counts=True)
    f_keys, f_counts = np.unique(fwd, return_counts=True)
    r_keys, r_counts = np.unique(rev, return_counts=True)
    fc = np.zeros(len(keys), np.int64)
    rc = np.zeros(len(keys), np.int64)
    fc[np.searchsorted(keys, f_keys)] = f_counts
    rc[np.searchsorted(keys, r_keys)] = r_counts
    return int(np.abs(fc - rc).sum() // 2)


def split_shells(mesh: trimesh.Trimesh) -> list[trimesh.Trimesh]:
    """Connected components of ``mesh`` (faces joined through shared vertices), unprocessed."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    faces = np.asarray(mesh.faces, dtype=np.int64)
    n_v = len(mesh.vertices)
    if len(faces) == 0:
        return []
    rows = np.repeat(np.arange(len(faces)), 3)
    # faces i, j connected when they share a vertex: components of the bipartite face-vertex graph
    full = coo_matrix(
        (np.ones(rows.size), (rows, len(faces) + faces.reshape(-1))), shape=(len(faces) + n_v, len(faces) + n_v)
    )
    _, labels = connected_components(full, directed=False)
    face_label = labels[: len(faces)]
    shells = []
    for lab in np.unique(face_label):
        f = faces[face_label == lab]
        used, inverse = np.unique(f.reshape(-1), return_inverse=True)
        shells.append(
            trimesh.Trimesh(vertices=np.asarray(mesh.vertices)[used], faces=inverse.reshape(-1, 3), process=False)
        )
    return shells


def _signed_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    v0, v1, v2 = (vertices[faces[:, k]] for k in range(3))
    return float(np.einsum("ij,ij->i", v0, np.cross(v1, v2)).sum() / 6.0)


def read_mesh(path: str | os.PathLike[str], frame: str) -> trimesh.Trimesh:
    """Read one closed triangle mesh (STL, OBJ or PLY, mm) and return it in the patient frame.

    Args:
        path: the file.
        frame: coordinate system of the file: ``"LPS"``, ``"RAS"`` or ``"patient"``.

    Returns:
        A ``trimesh.Trimesh`` (vertices merged, faces as in the file), patient frame, mm.

    Raises:
        InputError: unknown frame or suffix, missing or unreadable file, not a mesh, no
            triangles, non-finite vertices, a frame contradicting the file's header, an open
            (not watertight) or inward-oriented surface. One line naming the file.
    """
    p = Path(path)
    frame = _check_frame(frame, str(p))
    suffix = p.suffix.lower()
    if suffix not in MESH_SUFFIXES:
        raise InputError(
            f"{p}: unknown anatomy format {p.suffix!r} (expected a mesh .stl, .obj or .ply, or a segmentation .seg.nrrd, .nrrd, .nii or .nii.gz)"
        )
    data = read_bytes(p, MAX_MESH_BYTES)  # a regular file of at most 1 GiB, else InputError
    binary_stl = suffix == ".stl" and _sniff_stl(p, data)
    declared = _declared_frame(data[:80] if binary_stl else data[:_HEADER_BYTES])
    if declared is not None and declared != frame:
        raise InputError(f"{p}: the file declares its coordinate system as {declared} but frame {frame!r} was given")
    try:
        loaded = trimesh.load(str(p), force="mesh", process=False)
    except Exception as exc:  # trimesh raises many types for malformed files
        detail = " ".join(str(exc).split()) or type(exc).__name__
        raise InputError(f"{p}: cannot read as a {suffix[1:].upper()} mesh ({detail[:200]})") from exc
    if not isinstance(loaded, trimesh.Trimesh):
        raise InputError(f"{p}: not a triangle mesh ({type(loaded).__name__})")
    vertices = np.asarray(loaded.vertices, dtype=np.float64)
    faces = np.asarray(loaded.faces, dtype=np.int64).reshape(-1, 3)
    if len(faces) == 0:
        n_points = len(vertices)
        if not n_points:  # force="mesh" drops bare points: look again without it
            try:
                plain = trimesh.load(str(p), process=False)
                n_points = len(getattr(plain, "vertices", ()))
            except Exception:
                n_points = 0
        what = f"a point cloud ({n_points} points, no triangles)" if n_points else "no triangles"
        raise InputError(f"{p}: holds {what}; expected a closed triangle mesh")
    if not np.isfinite(vertices).all():
        bad = int((~np.isfinite(vertices).all(axis=1)).sum())
        raise InputError(f"{p}: {bad} vertices have non-finite (NaN or inf) coordinates")
    if len(vertices) and float(np.abs(vertices).max()) > COORDINATE_LIMIT_MM:
        raise InputError(
            f"{p}: a vertex coordinate of {float(np.abs(vertices).max()):g} mm is beyond the "
            f"±{COORDINATE_LIMIT_MM:g} mm range (a unit mistake?)"
        )
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise InputError(f"{p}: a face refers to a vertex that does not exist")
    mesh = trimesh.Trimesh(vertices=vertices, faces=faces, process=False)
    mesh.merge_vertices()
    unmatched = _unmatched_edges(np.asarray(mesh.faces))
    if unmatched:
        raise InputError(
            f"{p}: surface is not closed (not watertight): {unmatched} edges without a "
            "matching opposite edge (holes or inconsistently oriented faces)"
        )
    for k, shell in enumerate(split_shells(mesh), start=1):
        if _signed_volume(np.asarray(shell.vertices), np.asarray(shell.faces)) <= 0.0:
            raise InputError(
                f"{p}: shell {k} encloses no positive volume (faces oriented inward or flat); "
                "expected outward-facing closed surfaces"
            )
    out = np.asarray(mesh.vertices) @ _TO_PATIENT[frame].T
    return trimesh.Trimesh(vertices=out, faces=np.asarray(mesh.faces), process=False)


def read_meshes(paths: Iterable[str | os.PathLike[str]], frame: str) -> list[trimesh.Trimesh]:
    """:func:`read_mesh` for each path (same frame for all), in order."""
    return [read_mesh(p, frame) for p in paths]


def _stl_bytes(vertices: np.ndarray, faces: np.ndarray, header: str) -> bytes:
    tri = vertices[faces]  # (F, 3, 3)
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(normal, axis=1, keepdims=True)
    normal = np.divide(normal, length, out=np.zeros_like(normal), where=length > 0)
    record = np.zeros(len(faces), dtype=np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")]))
    record["n"] = normal
    record["v"] = tri
    head = header.encode("ascii")[:80].ljust(80, b" ")
    return head + np.uint32(len(faces)).astype("<u4").tobytes() + record.tobytes()


def write_stl(
    mesh_or_meshes: trimesh.Trimesh | Sequence[trimesh.Trimesh], path: str | os.PathLike[str], frame: str = "patient"
) -> Path:
    """Write one mesh or several (one file, each kept as its own closed shell) as binary STL.

    The meshes are in the patient frame; ``frame`` ("patient", "LPS" for 3D Slicer, or "RAS")
    is the coordinate system of the file, declared in its 80-byte header. Coordinates are
    stored as float32 (STL), about 1e-5 mm at 100 mm. The write is atomic.

    Returns:
        The path written.
    """
    target = Path(path)
    frame = _check_frame(frame, str(target))
    meshes = [mesh_or_meshes] if isinstance(mesh_or_meshes, trimesh.Trimesh) else list(mesh_or_meshes)
    if not meshes or not all(isinstance(m, trimesh.Trimesh) for m in meshes):
        raise InputError(f"{target}: nothing to write (expected trimesh.Trimesh meshes)")
    vertices, faces, offset = [], [], 0
    for m in meshes:
        vertices.append(np.asarray(m.vertices, dtype=np.float64))
        faces.append(np.asarray(m.faces, dtype=np.int64) + offset)
        offset += len(m.vertices)
    v = np.concatenate(vertices) @ _TO_PATIENT[frame]  # inverse of a rotation: transpose
    f = np.concatenate(faces)
    tag = "frame=patient (x right, y superior, z posterior)" if frame == "patient" else f"SPACE={frame}"
    try:
        atomic_write_bytes(target, _stl_bytes(v, f, f"arcube anatomy, mm, {tag}"))
    except OSError as exc:
        raise InputError(f"{target}: cannot write ({exc.strerror or exc})") from exc
    return target
