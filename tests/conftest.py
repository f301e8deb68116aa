"""Shared fixtures. Houses use the built-in box assets unless a test needs the real furniture."""

from __future__ import annotations

import pytest

from efficienteqa.envs.synthetic.env import SyntheticEnv
from efficienteqa.envs.synthetic.primitives import builtin_catalog
from efficienteqa.geometry import CameraSpec


def egl_available() -> bool:
    try:
        import moderngl

        moderngl.create_standalone_context(backend="egl").release()
        return True
    except Exception:
        return False


needs_egl = pytest.mark.skipif(
    not egl_available(), reason="no EGL (apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri)")


@pytest.fixture(scope="session")
def catalog():
    return builtin_catalog()


@pytest.fixture(scope="session")
def small_camera() -> CameraSpec:
    return CameraSpec().scaled(160, 120)


@pytest.fixture(scope="session")
def env_seed3(catalog) -> SyntheticEnv:
    from efficienteqa.envs.synthetic.generate import generate_house

    env = SyntheticEnv(generate_house(3, catalog, "builtin"), catalog)
    yield env
    env.close()
