"""The explore module in synthetic houses: safe paths, progress, semantic values painted."""

import numpy as np
import pytest

from conftest import needs_egl
from efficienteqa.envs.synthetic.env import SyntheticEnv
from efficienteqa.envs.synthetic.generate import generate_house
from efficienteqa.explore.module import ExploreModule, SemanticScore
from efficienteqa.explore.registry import make_explorer
from efficienteqa.geometry import CameraSpec
from efficienteqa.mapping.maps2d import Mapper
from efficienteqa.mapping.tsdf import VolumeSpec

pytestmark = needs_egl
CAMERA = CameraSpec().scaled(320, 240)


def _module(env, explorer, scorer=None):
    lo, hi = env.bounds
    mapper = Mapper(VolumeSpec.around(lo[:2], hi[:2], 0.0), 0.0, (env.house.start.x, env.house.start.y))
    return ExploreModule(mapper, make_explorer(explorer), scorer, seed=1)


def _episode(env, module, steps):
    obs, _ = env.reset()
    outs, blocked = [], 0
    for step in range(1, steps + 1):
        out = module.step(obs, step, "Where is the sofa?")
        outs.append(out)
        if out.decision.done:
            break
        obs, _, _, _, info = env.step(out.decision.pose)
        if info["blocked"]:
            blocked += 1
            module.blocked((out.decision.pose.x, out.decision.pose.y))
    return outs, blocked


@pytest.mark.parametrize("seed", [1, 3])
def test_paths_never_cross_walls_or_furniture(catalog, seed):
    with SyntheticEnv(generate_house(seed, catalog, "builtin"), catalog, CAMERA) as env:
        outs, blocked = _episode(env, _module(env, "frontier-only"), 20)
        assert blocked <= 1
        for out in outs:
            path = out.decision.path
            for a, b in zip(path[:-1], path[1:]):
                for t in np.linspace(0, 1, max(2, int(np.linalg.norm(b - a) / 0.05) + 1)):
                    x, y = a + t * (b - a)
                    i, j = env.grid.spec.world_to_cell((x, y))
                    assert env.grid.free[i, j], f"step {out.step} path crosses an obstacle"
        explored = outs[-1].state.explored.sum() * 0.01  # m^2 at 0.1 m cells
        assert explored > 0.2 * env.floor_area_m2  # measured 57% and 27% in these two houses


class _LeftmostScorer:
    """Always prefers letter A, always says 'worth exploring'."""

    def __init__(self):
        self.calls = 0

    def score(self, obs, prompts, question):
        self.calls += 1
        return SemanticScore({"A": 90.0, "B": 10.0}, 1.0)


def test_semantic_values_are_painted_from_the_scorer(catalog):
    scorer = _LeftmostScorer()
    with SyntheticEnv(generate_house(3, catalog, "builtin"), catalog, CAMERA) as env:
        module = _module(env, "sfe", scorer)
        outs, _ = _episode(env, module, 4)
    prompted = [o for o in outs if o.prompts]
    assert prompted and scorer.calls == len(prompted)
    first = prompted[0]
    assert first.lsv["A"] > first.lsv.get("B", 0.0) and first.gsv == pytest.approx(np.exp(2) / 3)
    values = module.values.raw
    a = first.prompts[0]
    i, j = module.mapper.spec.world_to_cell(a.xy)
    assert values[i, j] > 0
    # Each step carries the smoothed map as painted by then (for pictures), warm-up included.
    assert all(o.values is not None for o in outs)
    assert outs[-1].values == pytest.approx(module.values.smoothed())
    assert first.values[i, j] > 0 and first.values.sum() < outs[-1].values.sum()
