import numpy as np
import pytest

from conftest import needs_egl
from efficienteqa.envs.base import Environment
from efficienteqa.envs.checks import check_env
from efficienteqa.envs.synthetic.env import SyntheticEnv
from efficienteqa.envs.synthetic.generate import ROBOT_RADIUS_M, generate_house
from efficienteqa.geometry import CameraSpec, Pose2D, backproject
from efficienteqa.mapping.navgrid import truncate_path

pytestmark = needs_egl


def test_intrinsics_of_the_paper_camera():
    cam = CameraSpec()
    assert cam.fx == pytest.approx(184.75, abs=0.01)
    assert cam.fy == pytest.approx(184.75, abs=0.01)
    assert cam.intrinsics[0, 2] == 320 and cam.intrinsics[1, 2] == 240


def _moves(env: SyntheticEnv, n: int = 3) -> list[Pose2D]:
    """Poses 3 m apart along the path to the farthest room centre."""
    start = (env.house.start.x, env.house.start.y)
    far = max(env.house.layout.rooms, key=lambda r: np.hypot(r.centre[0] - start[0],
                                                             r.centre[1] - start[1]))
    path = env.grid.shortest_path(start, far.centre, ROBOT_RADIUS_M, snap_m=1.5)
    assert path is not None
    out = []
    for k in range(1, n + 1):
        xy = truncate_path(path, 3.0 * k)
        out.append(Pose2D(float(xy[0]), float(xy[1]), 0.5 * k))
    return out


def test_contract(catalog, small_camera):
    with SyntheticEnv(generate_house(1, catalog, "builtin"), catalog, small_camera) as env:
        assert isinstance(env, Environment)
        check_env(env, _moves(env))


def test_blocked_move_leaves_the_robot_in_place(catalog, small_camera):
    with SyntheticEnv(generate_house(1, catalog, "builtin"), catalog, small_camera) as env:
        env.reset()
        wall = env.house.layout.walls[0]
        obs, *_, info = env.step(Pose2D((wall.x0 + wall.x1) / 2, (wall.y0 + wall.y1) / 2, 0.0))
        assert info["blocked"] and obs.pose == env.house.start
        with pytest.raises(ValueError):
            env.reset(options={"start": Pose2D(-5.0, -5.0, 0.0)})


def test_depth_and_pose_agree_with_the_house(env_seed3):
    """Floor pixels back-project to z = 0; object pixels land inside the object's box."""
    obs, _ = env_seed3.reset()
    pts = backproject(obs.depth_m, obs.intrinsics, obs.cam_to_world)
    rooms = env_seed3.house.layout.rooms
    in_room = np.zeros(obs.depth_m.shape, bool)
    for r in rooms:  # away from walls, a low structure pixel can only be floor
        in_room |= ((pts[..., 0] > r.x0 + 0.15) & (pts[..., 0] < r.x1 - 0.15)
                    & (pts[..., 1] > r.y0 + 0.15) & (pts[..., 1] < r.y1 - 0.15))
    floor = (obs.instance == 0) & (pts[..., 2] < 0.5) & in_room
    assert floor.sum() > 1000
    assert np.abs(pts[floor][:, 2]).max() < 0.03
    for oid in set(np.unique(obs.instance)) - {0, -1}:
        o = env_seed3.house.object(int(oid))
        p = pts[obs.instance == oid]
        inside = np.hypot(p[:, 0] - o.x, p[:, 1] - o.y) <= np.hypot(*o.size_m[:2]) / 2 + 0.05
        assert inside.mean() > 0.98, f"pixels of {o.category} are not where it stands"
        assert p[:, 2].min() >= o.z - 0.05 and p[:, 2].max() <= o.top_z + 0.05
