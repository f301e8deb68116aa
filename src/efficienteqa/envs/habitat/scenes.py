"""Where an HM3D scene's files are, and where an HM-EQA episode starts: paths and rows, no
simulator.

HM-EQA names scenes by their HM3D folder, e.g. "00800-TEEsavR23oF"; the files inside drop the
five-digit index: ``<root>/00800-TEEsavR23oF/TEEsavR23oF.basis.glb`` and ``.basis.navmesh``,
with ``TEEsavR23oF.semantic.glb`` + ``.semantic.txt`` where the scene has HM3D-Semantics
annotations. ``root`` may also hold the split folders of the HM3D download (``train/``,
``val/``, ``minival/``); they are searched in that order.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from efficienteqa.errors import EfficientEQAError

SPLITS = ("", "train", "val", "minival")
DATASET_CONFIG = "hm3d_annotated_basis.scene_dataset_config.json"
FIX_ROOT = ("pass --hm3d-root FOLDER holding the HM3D scene folders (e.g. 00800-TEEsavR23oF/), "
            "see docs/habitat.md")


@dataclass(frozen=True)
class HabitatStart:
    """A start pose in Habitat's own frame: ``position`` metres (y up), ``yaw_rad`` about +y."""

    position: tuple[float, float, float]
    yaw_rad: float

    @classmethod
    def from_source(cls, source: dict[str, Any]) -> HabitatStart | None:
        """The start pose of an HM-EQA question (``EvalQuestion.source``), None if it has none."""
        position, yaw = source.get("habitat_position"), source.get("habitat_yaw")
        if position is None or yaw is None:
            return None
        x, y, z = (float(v) for v in position)
        return cls((x, y, z), float(yaw))


@dataclass(frozen=True)
class SceneFiles:
    """The files Habitat-Sim loads for one scene; ``semantic`` and ``dataset_config`` are None
    where the scene has no annotations (or no config names them)."""

    scene: str
    glb: Path
    navmesh: Path
    semantic: Path | None
    dataset_config: Path | None


def file_stem(scene: str) -> str:
    """"00800-TEEsavR23oF" -> "TEEsavR23oF" (HM-EQA's ``scene[6:]``)."""
    index, dash, stem = scene.partition("-")
    if not (dash and index.isdigit() and len(index) == 5 and stem):
        raise EfficientEQAError(f"{scene!r} is not an HM3D scene name",
                                fix="scene names look like 00800-TEEsavR23oF (hm3d:00800-TEEsavR23oF)")
    return stem


def check_root(root: Path | str) -> Path:
    """``root`` as a path, if it is a folder."""
    path = Path(root).expanduser()
    if not path.is_dir():
        raise EfficientEQAError(f"HM3D root {root} is not a folder", fix=FIX_ROOT)
    return path


def find_scene(root: Path, scene: str) -> SceneFiles:
    """The files of ``scene`` under ``root`` (or under one of its split folders)."""
    stem = file_stem(scene)
    root = check_root(root)
    folder = next((root / split / scene for split in SPLITS if (root / split / scene).is_dir()), None)
    if folder is None:
        raise EfficientEQAError(f"scene {scene} is not under {root}", fix=FIX_ROOT)
    glb, navmesh = folder / f"{stem}.basis.glb", folder / f"{stem}.basis.navmesh"
    missing = [p.name for p in (glb, navmesh) if not p.is_file()]
    if missing:
        raise EfficientEQAError(f"scene folder {folder} lacks {', '.join(missing)}",
                                fix="download the HM3D 'habitat' files (glb + navmesh) of the scene")
    semantic = folder / f"{stem}.semantic.glb"
    has_semantic = semantic.is_file() and semantic.with_suffix(".txt").is_file()
    config = next((p / DATASET_CONFIG for p in (folder.parent, folder.parent.parent, root)
                   if (p / DATASET_CONFIG).is_file()), None)
    return SceneFiles(scene, glb, navmesh, semantic if has_semantic else None,
                      config if has_semantic else None)
