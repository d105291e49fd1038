"""The 3D view of a recorded run: the plant posed at a recorded ``qpos``, drawn by MuJoCo,
and the plot strip drawn under it.

Nothing is simulated: :func:`pose_data` sets the positions and calls
``mj_kinematics``. The plot strip is drawn once with matplotlib (the whole
replayed window); each frame only adds its time cursor (:func:`draw_cursor`),
a column of pixels, so the strip costs almost nothing per frame.

MuJoCo and matplotlib are imported where a scene or a strip is made, not with
this module: the commands that import it refuse a bad option within a second,
and a render worker must set ``MUJOCO_GL`` before MuJoCo is first imported.
"""

from __future__ import annotations

import math

import numpy as np

from simpro_mj.report.recording import Recording

__all__ = [
    "CAMERAS",
    "ReplayScene",
    "draw_cursor",
    "label_image",
    "plot_strip",
    "pose_data",
    "replay_model",
]

#: Named cameras of the MJCF, the first the default.
CAMERAS = ("three_quarter", "side", "driver")


def replay_model(scenario: dict):
    """The run's plant (its ``plant`` parameters) as ``(MjModel, MjData)``."""
    import mujoco

    from simpro_mj.plant.model import load_model  # MuJoCo's model builder

    model = load_model(scenario.get("plant"))
    return model, mujoco.MjData(model)


def pose_data(model, data, qpos, ghost_pos=None, ghost_quat=None) -> None:
    """Put a recorded ``qpos`` (and the ghost's pose) into ``data``; no physics.

    ``mj_kinematics`` places the bodies, ``mj_camlight`` the cameras and
    lights that follow them; nothing else is computed, nothing integrated.
    """
    import mujoco

    data.qpos[:] = qpos
    if ghost_pos is not None:
        data.mocap_pos[0] = ghost_pos
        data.mocap_quat[0] = ghost_quat
    mujoco.mj_kinematics(model, data)
    mujoco.mj_camlight(model, data)


class ReplayScene:
    """A recorded run posed at given rows and drawn by :class:`mujoco.Renderer`.

    Parameters
    ----------
    scenario : dict
        The run's resolved scenario (its ``plant`` rebuilds the same model).
    width, height : int
        Image size in pixels.
    camera : str
        One of :data:`CAMERAS`.
    ghost : bool
        Draw the set-point ghost (otherwise it is hidden).
    shadows : bool
        Cast shadows: about 3x the cost of a frame with Mesa's software
        renderer (docs/performance.md), so off by default.
    """

    def __init__(
        self,
        scenario: dict,
        width: int,
        height: int,
        camera: str,
        ghost: bool = True,
        shadows: bool = False,
    ):
        import mujoco

        self.model, self.data = m, _ = replay_model(scenario)
        m.vis.global_.offwidth = max(int(m.vis.global_.offwidth), width)
        m.vis.global_.offheight = max(int(m.vis.global_.offheight), height)
        self.camera = camera
        self.renderer = mujoco.Renderer(m, height, width)
        self.option = mujoco.MjvOption()
        self.option.geomgroup[1] = 1 if ghost else 0
        self.renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = bool(shadows)

    def pose(self, qpos, ghost_pos=None, ghost_quat=None) -> None:
        """Set the recorded ``qpos`` (and the ghost's pose): :func:`pose_data`."""
        pose_data(self.model, self.data, qpos, ghost_pos, ghost_quat)

    def render(self) -> np.ndarray:
        """RGB image (height, width, 3) uint8 of the current pose."""
        self.renderer.update_scene(self.data, camera=self.camera, scene_option=self.option)
        return self.renderer.render()

    def segmentation(self) -> np.ndarray:
        """Geom id per pixel (-1: background), (height, width) int32."""
        r = self.renderer
        r.enable_segmentation_rendering()
        try:
            r.update_scene(self.data, camera=self.camera, scene_option=self.option)
            seg = r.render()
        finally:
            r.disable_segmentation_rendering()
        ids = seg[..., 0].copy()
        import mujoco

        ids[seg[..., 1] != int(mujoco.mjtObj.mjOBJ_GEOM)] = -1
        return ids

    def close(self) -> None:
        self.renderer.close()


def plot_strip(rec: Recording, width: int, height: int, t0: float, t1: float):
    """The plots under the 3D view, drawn once; the cursor is added per frame.

    Four panels: set-point and pose for roll, pitch (deg) and heave (mm), and
    the three valve voltages (V), over the replayed window.

    Returns
    -------
    image : ndarray (height, width, 3) uint8
    boxes : list of (x0, x1, y0, y1)
        Pixel extent of each panel's plotting area (where the cursor goes).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    dpi = 100.0
    fig = Figure(figsize=(width / dpi, height / dpi), dpi=dpi)
    FigureCanvasAgg(fig)
    c, t = rec.columns, rec.columns["time_s"]
    sel = (t >= t0 - 1e-9) & (t <= t1 + 1e-9)
    small = max(4.0, min(8.0, width / 110.0))
    panels = [
        ("roll [deg]", "roll_ref_rad", "roll_rad", 180.0 / math.pi),
        ("pitch [deg]", "pitch_ref_rad", "pitch_rad", 180.0 / math.pi),
        ("heave [mm]", "heave_ref_m", "heave_m", 1e3),
    ]
    axes = fig.subplots(1, 4)
    for ax, (label, ref, real, scale) in zip(axes[:3], panels, strict=True):
        ax.plot(t[sel], c[ref][sel] * scale, color="0.55", lw=0.8, ls="--", label="set-point")
        ax.plot(t[sel], c[real][sel] * scale, color="tab:blue", lw=1.0, label="pose")
        ax.set_title(label, fontsize=small, pad=2)
    for i, color in zip((1, 2, 3), ("tab:orange", "tab:green", "tab:purple"), strict=True):
        axes[3].plot(t[sel], c[f"u{i}_v"][sel], color=color, lw=0.8, label=f"u{i}")
    axes[3].set_title(f"valves [V] ({rec.name})", fontsize=small, pad=2)
    axes[0].legend(fontsize=small * 0.8, loc="best", frameon=False)
    for ax in axes:
        ax.set_xlim(t0, t1)
        ax.ticklabel_format(axis="y", useOffset=False)  # 1265.0 mm, not +1.265e3
        ax.tick_params(labelsize=small * 0.85, length=2, pad=1)
        ax.set_xlabel("t [s]", fontsize=small * 0.85, labelpad=1)
    fig.subplots_adjust(left=0.05, right=0.99, bottom=0.22, top=0.86, wspace=0.35)
    fig.canvas.draw()
    img = np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()
    boxes = []
    for ax in axes:
        (x0, y0), (x1, y1) = ax.get_window_extent().get_points()
        # figure pixels have y up; the image's rows go down
        boxes.append(
            (int(round(x0)), int(round(x1)), int(round(height - y1)), int(round(height - y0)))
        )
    return img, boxes


def label_image(text: str, height: int) -> np.ndarray:
    """A small white-on-dark RGB label (drawn once with matplotlib, pasted per frame)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    h = max(10, int(height * 0.06)) // 2 * 2
    w = max(2 * h, int(0.62 * h * (len(text) + 1))) // 2 * 2
    fig = Figure(figsize=(w / 100.0, h / 100.0), dpi=100.0, facecolor=(0.1, 0.1, 0.12))
    FigureCanvasAgg(fig)
    fig.text(0.5, 0.5, text, color="white", ha="center", va="center", fontsize=h * 0.5)
    fig.canvas.draw()
    return np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()


def draw_cursor(strip: np.ndarray, boxes, frac: float) -> np.ndarray:
    """A copy of the strip with a red time cursor at ``frac`` (0..1) of each panel."""
    out = strip.copy()
    for x0, x1, y0, y1 in boxes:
        x = int(round(x0 + frac * (x1 - x0)))
        x = min(max(x, x0), max(x1 - 1, x0))
        out[max(y0, 0) : y1, max(x - 1, 0) : x + 1] = (220, 30, 30)
    return out
