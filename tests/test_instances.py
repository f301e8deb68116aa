"""Objects as 3-D instances of the episode's map (mapping/instances.py; DESIGN 9):
regions of many views merged by 3-D overlap into instances, counted once."""

from __future__ import annotations

import numpy as np

from efficienteqa.mapping.instances import SURE, InstanceMap, Region, count


def _box(x: float, y: float, size: tuple[float, float, float], z0: float = 0.0,
         step: float = 0.03) -> np.ndarray:
    """Points filling a box whose footprint is centred on (x, y), from z0 up."""
    sx, sy, sz = size
    g = np.mgrid[x - sx / 2:x + sx / 2:step, y - sy / 2:y + sy / 2:step, z0:z0 + sz:step]
    return g.reshape(3, -1).T


def _chair(x: float, y: float) -> np.ndarray:
    return _box(x, y, (0.45, 0.45, 0.9))


def _side(points: np.ndarray, axis: int, low: bool) -> np.ndarray:
    """The half of the points a view from one side sees (the others hidden)."""
    mid = np.median(points[:, axis])
    return points[points[:, axis] <= mid] if low else points[points[:, axis] >= mid]


def test_two_views_of_one_chair_are_one_instance():
    chair = _chair(2.0, 1.0)
    m = InstanceMap()
    a = m.add([Region("chair", _side(chair, 0, low=True))])  # from the -x side
    b = m.add([Region("chair", _side(chair, 1, low=False))])  # from the +y side
    c = m.add([Region("chair", chair[::3] + np.array([0.04, -0.03, 0.0]))])  # nearly all
    assert a.ids == b.ids == c.ids
    assert len(m) == 1 and m.instances()[0].views == 3


def test_two_chairs_0_6_m_apart_are_two_in_one_view_and_across_views():
    left, right = _chair(2.0, 1.0), _chair(2.6, 1.0)
    m = InstanceMap()
    first = m.add([Region("chair", left), Region("chair", right)])
    assert len(set(first.ids)) == 2
    # later views each see one of them, from another side: still two
    m.add([Region("chair", _side(left, 1, low=True))])
    m.add([Region("chair", _side(right, 1, low=False))])
    assert len(m.instances()) == 2
    # and two chairs 0.6 m apart seen in different views only are two as well
    m2 = InstanceMap()
    m2.add([Region("chair", left)])
    m2.add([Region("chair", right)])
    assert len(m2.instances()) == 2


def test_a_cup_on_a_table_is_not_the_table_and_stands_on_it():
    table = _box(3.0, 3.0, (1.2, 0.8, 0.05), z0=0.7)  # its top, as the camera sees it
    cup = _box(3.1, 3.0, (0.08, 0.08, 0.1), z0=0.75, step=0.02)
    m = InstanceMap()
    for _ in range(2):
        seen = m.add([Region("table", table), Region("cup", cup, support=0)])
        assert seen.ids[0] != seen.ids[1]
    assert sorted(i.category for i in m.instances()) == ["cup", "table"]
    cup_instance = next(i for i in m.instances() if i.category == "cup")
    assert cup_instance.support == seen.ids[0]


def test_an_unsure_object_seen_in_three_views_is_one_sure_instance():
    plant = _box(1.0, 4.0, (0.4, 0.4, 0.8))
    unsure = SURE / 3 + 0.01  # each view alone is not sure
    m = InstanceMap()
    for n, part in enumerate((_side(plant, 0, True), _side(plant, 1, True), plant)):
        m.add([Region("plant", part, unsure)])
        assert len(m) == 1
        assert (len(m.instances()) == 1) == (n == 2)  # sure only after the third view
    assert m.instances()[0].confidence > SURE


def test_a_region_of_another_category_joins_only_when_it_is_the_same_place():
    chair = _chair(2.0, 1.0)
    m = InstanceMap()
    m.add([Region("chair", chair, 0.9)])
    m.add([Region("armchair", chair[::2], 0.7)])  # the same chair, misnamed in one view
    m.add([Region("chair", chair, 0.9)])
    assert len(m) == 1 and m.instances()[0].category == "chair"
    m.add([Region("table", _box(2.0, 1.5, (1.0, 0.6, 0.05), z0=0.7))])  # beside it, overlapping
    assert len(m) == 2


def test_keyed_regions_are_one_instance_per_key_whatever_the_place():
    """The semantic sensor's object ids are instances already: nothing is merged by place."""
    m = InstanceMap()
    a, b = _chair(2.0, 1.0), _chair(2.0, 1.0)  # one place, two ids (a stacked chair)
    m.add([Region("chair", a, key=7), Region("chair", b, key=8)])
    m.add([Region("chair", a[::2] + 0.4, key=7)])  # id 7 seen elsewhere: still id 7's
    assert len(m) == 2
    assert {i.key for i in m.instances()} == {7, 8}
    assert all(i.views == (2 if i.key == 7 else 1) for i in m.instances())


def test_a_region_that_joins_two_instances_never_seen_together_merges_them():
    chair = _chair(2.0, 1.0)
    back = chair[chair[:, 2] > 0.6]  # seen first from above the table: its back only
    legs = chair[chair[:, 2] < 0.3] + np.array([0.0, 0.0, 0.0])
    m = InstanceMap()
    m.add([Region("chair", back)])
    m.add([Region("chair", legs)])  # no shared voxel, places 0.0 m apart: one by place
    m.add([Region("chair", chair)])
    assert len(m) == 1


def test_count_is_the_sure_members_around_the_support_in_the_place_asked():
    m = InstanceMap()
    table = _box(3.0, 3.0, (1.2, 0.8, 0.75))
    chairs = [_chair(3.0 + dx, 3.0 + dy) for dx, dy in ((-0.9, 0), (0.9, 0), (0, 0.7))]
    far = _chair(6.0, 3.0)  # a chair of the same room, not at the table
    for view in range(3):  # every view sees the table and the chairs, in varying parts
        m.add([Region("table", table, room="dining room"),
               *(Region("chair", _side(c, view % 2, view == 1)) for c in chairs),
               Region("chair", far)])
    got = count(m, lambda c: c == "chair", lambda c: c == "table",
                lambda i: i.room in (None, "dining room"))
    assert got is not None and got.n == 3
    assert count(m, lambda c: c == "chair", lambda c: c == "table",
                 lambda i: i.room == "kitchen") is None
    assert count(m, lambda c: c == "chair").n == 4  # type: ignore[union-attr]


# ----- the count gate reads the instance map --------------------------------------------------
class _Frame:  # what the gate reads of an observation: its size
    depth_m = np.zeros((480, 640), np.float32)


class _Perception:
    """A text perception keeping an instance map, as the semantic sensor and the pixels do:
    the frame's text (a table and two chairs, in the dining room), its sightings and its
    regions, set per frame by the test."""

    def __init__(self, with_instances: bool = True):
        from efficienteqa.envs.base import ObjectLabel
        from efficienteqa.perception.visible import FrameDescription, VisibleObject

        def told(category: str, iid: int) -> VisibleObject:
            return VisibleObject(iid, ObjectLabel(category, "brown", None, None), 5000,
                                 (320.0, 240.0), 0.0, "ahead", 2.0)

        self.d = FrameDescription("", "dining room",
                                  (told("table", 1), told("chair", 2), told("chair", 3)), ())
        self.regions: list[Region] = []
        self.instances = InstanceMap()
        if not with_instances:
            self.instances_seen = None  # type: ignore[assignment]

    def describe(self, obs):
        return self.d

    def sightings(self, obs, target):
        from efficienteqa.perception.base import Sighting, Sightings

        things = [Sighting(r.category, tuple(np.median(r.points[:, :2], axis=0)), 0.9, 800,
                           r.cut, "dining room") for r in self.regions]
        return Sightings({}, tuple(things))

    def instances_seen(self, obs, target):
        return self.instances.add(self.regions)


def _count_walk(with_instances: bool):
    """Three views of a table and its two chairs; in the second, the network cuts one chair in
    two (its back and its legs), as the pixel network's regions of chairs often are."""
    from efficienteqa.question import parse_question
    from efficienteqa.stop.gate import RulesGate

    q = "How many chairs are around the table in the dining room?"
    table = _box(0.0, 0.0, (1.2, 0.8, 0.75))
    a, b = _chair(0.0, 0.75), _chair(0.0, -0.75)
    perception = _Perception(with_instances)
    gate = RulesGate(perception)  # type: ignore[arg-type]
    target = parse_question(q)
    verdicts = []
    for chairs in ([a, b], [a[a[:, 2] > 0.5], a[a[:, 2] < 0.3] + [0.0, 0.25, 0.0], b], [a, b]):
        perception.regions = [Region("table", table), *(Region("chair", c) for c in chairs)]
        verdicts.append(gate.check(q, target, _Frame(), ""))  # type: ignore[arg-type]
    return verdicts


def test_the_count_gate_counts_the_instances_so_a_chair_cut_in_two_is_one_member():
    first, cut, again = _count_walk(with_instances=True)
    assert first.ok and first.final and first.why == "2 chair around the whole table"
    assert cut.ok and cut.why == "2 chair around the whole table"
    assert again.ok and again.final
    # merged by the sightings' places (no instance map), the cut chair is a third member and no
    # frame ever shows all three
    first, cut, again = _count_walk(with_instances=False)
    assert first.ok and not cut.ok and not again.ok
    assert again.why == "2 of the 3 chair seen around the table"


def test_the_answer_is_told_the_instance_maps_count():
    from efficienteqa.answer.views import count_note

    q = "How many chairs are around the table in the dining room?"
    view = "You are in the dining room. Visible: three brown chairs ahead, 1.2-1.6 m; a table."
    assert count_note(q, [view]) == "The view lists 3 chairs: the answer is 3."
    assert count_note(q, [view], counted=3) == "The view lists 3 chairs: the answer is 3."
    assert count_note(q, [view], counted=2) == (
        "Counting each one once over all its views, the robot saw 2 chairs around the table: "
        "the answer is 2.")
    assert count_note(q, [], counted=1).endswith("saw 1 chair around the table: the answer is 1.")


def test_the_semantic_sensor_fills_one_instance_per_object_id():
    """Its ids are instances already: the two chairs side by side stay two, and each object is
    one instance however many frames show it."""
    from efficienteqa.perception.semantic import SemanticPerception
    from test_semantic_perception import FakeLabels, make_frame

    perception = SemanticPerception(FakeLabels())  # type: ignore[arg-type]
    first = perception.instances_seen(make_frame())
    perception.instances_seen(make_frame())
    assert sorted(i.key for i in perception.instances.instances()) == [5, 7, 9, 11, 12]  # type: ignore[type-var]
    assert all(i.views == 2 and i.sure for i in perception.instances.instances())
    chairs = [i for i in perception.instances.instances() if i.category == "chair"]
    assert len(chairs) == 2 and chairs[0].room == "kitchen"
    obs = make_frame()
    assert perception.instances_seen(obs) is perception.instances_seen(obs)  # once per frame
    assert len(first.ids) == 5
    perception.reset()
    assert len(perception.instances) == 0


def test_a_count_questions_target_reads_the_map_in_the_room_it_names():
    from efficienteqa.mapping.instances import asked_count
    from efficienteqa.question import parse_question

    m = InstanceMap()
    table = _box(3.0, 3.0, (1.2, 0.8, 0.75))
    chairs = [_chair(3.0 + dx, 3.0) for dx in (-0.9, 0.9)]
    m.add([Region("table", table, room="dining room"),
           *(Region("chair", c, room="dining room") for c in chairs)])
    dining = parse_question("How many chairs are around the table in the dining room?")
    kitchen = parse_question("How many chairs are around the table in the kitchen?")
    got = asked_count(m, dining)
    assert got is not None and got.n == 2 and m[got.support].category == "table"  # type: ignore[index]
    assert asked_count(m, kitchen) is None
    assert asked_count(m, parse_question("What colour is the table?")) is None
    assert asked_count(None, dining) is None
