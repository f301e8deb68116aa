"""Pixel perception (DESIGN 9, learned perception): the frame's RGB-D read by the project's
own network, then described in the same words as the semantic sensor.

It reads the observation's RGB, depth, intrinsics and pose and nothing else: no instance buffer,
no scene labels, no floor plan. The network (``perception.pixels.net``) gives classes per pixel;
``segment.read_frame`` makes instances and per-frame labels of them; the semantic describer turns
those into the view, direction and relevancy texts and the sightings, so the rest of the pipeline
is unchanged. With ``room_votes`` (the stack builds the agent's perception so), rooms are named by
the episode's room votes (``rooms.RoomVotes``: floor evidence and the objects seen, per room
region of the map); ``reset`` starts them afresh, and the agent calls it as every episode starts.
Without (the default: frames of many houses read by one perception, as ``evaluate`` reads them),
each frame names rooms from its own floor. With ``fuse_views``, objects are fused over the
episode's views (``fusion.ObjectEvidence``); off by default (DESIGN 9: on validation walks it
traded objects right for objects found at about the rate a lower threshold does). With
``close_reads`` (``close.CloseReads``, or a number of crops; ``load`` gives CLOSE_READS), up to
that many supports in view are read again on a crop around each, and the small objects the crop
pass is sure of are pasted into the frame's classes (``close``): the agent's and ``perception
evaluate``'s perception read so; built directly, it is off.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from efficienteqa.mapping.instances import Region
from efficienteqa.observation import Observation
from efficienteqa.perception.base import Modality
from efficienteqa.perception.pixels.close import CloseReads, close_read
from efficienteqa.perception.pixels.fusion import ObjectEvidence
from efficienteqa.perception.pixels.rooms import PRIOR, RoomPrior, RoomVotes
from efficienteqa.perception.pixels.segment import PixelClasses, floor_types, read_frame
from efficienteqa.perception.semantic import SemanticPerception

if TYPE_CHECKING:
    from efficienteqa.envs.base import SceneLabels

# Said once where the network reads frames that look real (a robot, a robot's recording, HM3D's
# scans; ``envs.base.looks_real``):
# on 50 real frames it named sofas, showers, beds and toilets in a kitchenette (docs/perception.md).
REAL_FRAMES_NOTE = ("note: --backends.perception pixels was trained on synthetic renders only; on "
                    "a real camera's frames (or a scanned house's) it names objects and rooms "
                    "that are not there. Use an image VLM: --backends.perception rgb "
                    "--backends.vlm openai:gpt-4o")

WEIGHTS = Path(__file__).resolve().parent / "weights" / "pixels.pt"
CLOSE_READS = 2  # crops a frame (chosen on validation houses 3900-3909: DESIGN 9, close reads)
Classifier = Callable[[np.ndarray, np.ndarray], PixelClasses]  # (rgb, depth_m) -> classes


class PixelPerception(SemanticPerception):
    """``Perception`` from pixels: the semantic describer over the instances of a classifier
    of pixels (the committed network by default, see ``load``)."""

    name = "pixels"
    modality: Modality = "text"

    def __init__(self, classify: Classifier, room_votes: bool = False,
                 prior: RoomPrior | None = None, record: dict[str, Any] | None = None,
                 fuse_views: bool = False, close_reads: int | CloseReads = 0) -> None:
        super().__init__(labels=None)  # type: ignore[arg-type]  # read() is all that uses them
        self.classify = classify
        self.room_votes = room_votes
        self.prior = prior if prior is not None or not room_votes else RoomPrior.load(PRIOR)
        self.record = record or {}  # the weights' record (how they were made), when loaded
        self.fuse_views = fuse_views
        self.close_reads = (close_reads if isinstance(close_reads, CloseReads)
                            else CloseReads(crops=close_reads))
        self._votes: RoomVotes | None = None
        self._evidence: ObjectEvidence | None = ObjectEvidence() if fuse_views else None
        self._read: tuple[Observation, Observation, SceneLabels] | None = None

    def reset(self) -> None:
        """A new episode: the room votes and the fused objects start empty."""
        self._votes = None
        self._evidence = ObjectEvidence() if self.fuse_views else None
        self._read = None
        super().reset()

    @classmethod
    def load(cls, weights: Path | None = None, room_votes: bool = False,
             close_reads: int | CloseReads = CLOSE_READS) -> PixelPerception:
        """The committed network (or the one at ``weights``); one-line error when missing."""
        from efficienteqa.perception.pixels.net import load_weights, predict

        net, vocabulary, meta = load_weights(weights or WEIGHTS)
        thresholds = {str(k): float(v) for k, v in meta.get("region_thresholds", {}).items()}

        def classify(rgb: np.ndarray, depth_m: np.ndarray) -> PixelClasses:
            category, colour, state, confidence = predict(net, rgb, depth_m)
            return PixelClasses(category, colour, state, vocabulary.categories,
                                vocabulary.colours, vocabulary.states,
                                confidence.astype(np.float32), thresholds)

        return cls(classify, room_votes, record=meta, close_reads=close_reads)

    def regions(self, obs: Observation) -> list[Region]:
        """The frame's objects as regions of the instance map (``mapping.instances``): the
        network's regions from ``segment.UNSURE_MIN`` up, described or too unsure to be
        (other views may make them sure), each weighed by its confidence and size
        (``segment.map_objects``), standing on what the description says. No keys: they are
        merged across views by place."""
        _, labels = self.read(obs)
        objects = getattr(labels, "objects", [])
        described = {o.described: n for n, o in enumerate(objects) if o.described is not None}
        under = {o.instance_id: o.support_id for o in self.describe(obs).objects}
        out = []
        for o in objects:
            below = under.get(o.described) if o.described is not None else None
            out.append(Region(o.category, o.points, o.confidence, o.colour, o.room, None,
                              described.get(below) if below is not None else None, o.cut))
        return out

    def read(self, obs: Observation) -> tuple[Observation, SceneLabels]:
        if self._read is None or self._read[0] is not obs:  # the network runs once per frame
            classes = self.classify(obs.rgb, obs.depth_m)
            if self.close_reads.crops:
                classes, _ = close_read(self.classify, classes, obs.rgb, obs.depth_m,
                                        obs.intrinsics, self.close_reads)
            if self.room_votes and self._votes is None:
                self._votes = RoomVotes(floor_types(classes.categories), self.prior)
            instance, labels = read_frame(classes, obs.depth_m, obs.intrinsics,
                                          obs.cam_to_world, self._votes, self._evidence)
            seen = Observation(rgb=obs.rgb, depth_m=obs.depth_m, cam_to_world=obs.cam_to_world,
                               intrinsics=obs.intrinsics, pose=obs.pose, instance=instance)
            self._read = (obs, seen, labels)
        return self._read[1], self._read[2]
