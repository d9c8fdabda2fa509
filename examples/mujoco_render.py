"""Render an exported AR-CUBE MuJoCo model to a PNG, offscreen (no window, no GPU needed with Mesa).

    MUJOCO_GL=egl python examples/mujoco_render.py robot.xml robot.png

``MUJOCO_GL=egl`` (or ``osmesa``) selects an offscreen OpenGL; with neither available MuJoCo cannot
render and this script stops with an error. Needs ``mujoco``, ``numpy`` and ``Pillow``.
"""

from __future__ import annotations

import argparse
import os
import sys

os.environ.setdefault("MUJOCO_GL", "egl")

import mujoco  # noqa: E402
import numpy as np  # noqa: E402


def render(model_path: str, width: int = 1280, height: int = 960, azimuth: float = 135.0, elevation: float = -25.0) -> np.ndarray:
    """The model in its keyframe ``assembled``, seen from (azimuth, elevation) deg; an RGB array."""
    model = mujoco.MjModel.from_xml_path(model_path)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("assembled").id)
    mujoco.mj_forward(model, data)
    robot = [i for i in range(model.ngeom) if not model.geom(i).name.startswith("anatomy")]
    pts = data.geom_xpos[robot]
    centre = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
    extent = float(np.max(np.linalg.norm(pts - centre, axis=1)) + model.geom_rbound[robot].max())
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    cam.lookat[:] = centre
    cam.distance = 2.2 * extent
    cam.azimuth, cam.elevation = azimuth, elevation
    opt = mujoco.MjvOption()
    opt.sitegroup[:] = 0
    opt.sitegroup[3] = 1  # joint points and the drill tip
    with mujoco.Renderer(model, height=height, width=width) as renderer:
        renderer.update_scene(data, camera=cam, scene_option=opt)
        return renderer.render()


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description="Render an exported AR-CUBE model to PNG.")
    ap.add_argument("model")
    ap.add_argument("png")
    ap.add_argument("--width", type=int, default=1280)
    ap.add_argument("--height", type=int, default=960)
    ap.add_argument("--azimuth", type=float, default=135.0)
    ap.add_argument("--elevation", type=float, default=-25.0)
    args = ap.parse_args(argv)
    try:
        rgb = render(args.model, args.width, args.height, args.azimuth, args.elevation)
    except Exception as exc:  # no offscreen OpenGL
        sys.exit(f"error: cannot render offscreen ({type(exc).__name__}: {exc}); try MUJOCO_GL=egl or MUJOCO_GL=osmesa")
    from PIL import Image

    Image.fromarray(rgb).save(args.png)
    print(args.png)


if __name__ == "__main__":
    main()
