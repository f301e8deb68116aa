"""The semantic sensor of an HM3D-Semantics scene as ``SceneLabels`` (perception.semantic).

HM3D-Semantics names each annotated instance with a free-text category ("chair", "kitchen
cabinet", "wall") and no colour, state or room, so descriptions carry categories only and no room
names. Structure (walls, floors, ceilings) and unannotated surfaces become instance 0, the
canonical "structure" id.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from efficienteqa.envs.base import ObjectLabel

STRUCTURE = frozenset({"", "wall", "floor", "ceiling", "unknown", "misc", "void", "objects",
                       "remove", "unlabeled"})


def _semantic_id(obj: Any) -> int | None:
    sid = getattr(obj, "semantic_id", None)
    if sid is None:  # older releases: the id string ends with the instance number ("_12")
        tail = str(getattr(obj, "id", "")).rpartition("_")[2]
        sid = int(tail) if tail.isdigit() else None
    return None if sid is None else int(sid)


def _category(obj: Any) -> str:
    category = getattr(obj, "category", None)
    name = category.name() if category is not None else ""
    return " ".join(str(name).strip().lower().split())


class HabitatLabels:
    """Labels of the instance ids of ``semantic_scene`` (``Simulator.semantic_scene``)."""

    def __init__(self, semantic_scene: Any) -> None:
        self._labels: dict[int, ObjectLabel] = {}
        for obj in getattr(semantic_scene, "objects", None) or []:
            sid = None if obj is None else _semantic_id(obj)
            if sid is None or sid <= 0:
                continue
            name = _category(obj)
            if name not in STRUCTURE:
                self._labels[sid] = ObjectLabel(name, None, None, None)
        size = max(self._labels, default=0) + 1
        self._lut = np.zeros(size, dtype=np.int32)
        ids = np.fromiter(self._labels, dtype=np.int64, count=len(self._labels))
        self._lut[ids] = ids

    def label(self, instance_id: int) -> ObjectLabel | None:
        return self._labels.get(int(instance_id))

    def room_at(self, x: float, y: float) -> str | None:
        return None  # HM3D-Semantics has no room names

    def objects(self) -> dict[int, ObjectLabel]:
        """Every object's label by instance id (what a recording of the scene carries)."""
        return dict(self._labels)

    def instance_buffer(self, semantic: np.ndarray) -> np.ndarray:
        """The raw semantic sensor image -> canonical instance ids (int32, 0 = structure)."""
        raw = np.asarray(semantic).astype(np.int64)
        inside = (raw >= 0) & (raw < len(self._lut))
        return np.where(inside, self._lut[np.clip(raw, 0, len(self._lut) - 1)], 0).astype(np.int32)
