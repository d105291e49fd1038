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

from collections.abc import Mapping

import numpy as np

from simpro_mj.config.models import Scenario
from simpro_mj.report.recording import Recording

#: Named cameras of the MJCF, the first the default.
CAMERAS = ("three_quarter", "side", "driver")
#: The set-point ghost in the set-point's blue (the figures' and the strip's), against the
#: cabin's orange: in the model's green at 30 % over the 55 % orange cabin the two blended
#: into one yellow block.
GHOST_RGBA = (0.12, 0.47, 0.71, 0.45)
#: The cabin nearly opaque in a replay, so the ghost shows where the two differ.
CABIN_ALPHA = 0.9
#: The external cameras moved this fraction of the way to the platform's reference
#: point (1.265 m above the floor) along their line of sight: the platform fills the
#: view and a 3 deg pitch moves the cabin's ends by about 10 px at 640x480.
CAMERA_ZOOM = 0.25
#: Smallest text of a replay in pixels at 640x480 (tick labels of the strip, the time
#: overlay); smaller views scale it down (:func:`text_px`).
TEXT_PX = 12


def text_px(width: int, height: int) -> int:
    """:data:`TEXT_PX` scaled to a view of ``width`` x ``height`` (its 640x480 size)."""
    return max(4, int(round(TEXT_PX * min(1.0, width / 640.0, height / 480.0))))


def _restyle(m) -> None:
    """The ghost in :data:`GHOST_RGBA`, the cabin at :data:`CABIN_ALPHA`, the external
    cameras closer (:data:`CAMERA_ZOOM`); drawing only, nothing of the dynamics."""
    import mujoco

    for name, rgba in (("ghost", GHOST_RGBA), ("cabin", None)):
        mat = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_MATERIAL, name)
        if mat < 0:
            continue
        if rgba is None:
            m.mat_rgba[mat, 3] = CABIN_ALPHA
        else:
            m.mat_rgba[mat] = rgba
    target = np.array([0.0, 0.0, 1.265])
    for name in ("three_quarter", "side"):
        cam = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_CAMERA, name)
        if cam < 0:
            continue
        forward = -np.asarray(m.cam_mat0[cam]).reshape(3, 3)[:, 2]  # cameras look along -z
        distance = float(np.dot(target - m.cam_pos[cam], forward))
        if distance > 0:
            m.cam_pos[cam] = m.cam_pos[cam] + CAMERA_ZOOM * distance * forward


def replay_model(scenario: Scenario | Mapping):
    """The run's plant (its ``plant`` parameters) as ``(MjModel, MjData)``."""
    import mujoco

    from simpro_mj.plant.model import load_model  # MuJoCo's model builder

    plant = scenario.get("plant") if isinstance(scenario, Mapping) else scenario.plant.tree()
    model = load_model(plant)
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
        _restyle(m)
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

    Four panels: set-point (dashed, the ghost's blue) and pose (the figures'
    green) for roll, pitch (deg) and heave from home (mm), and the three valve
    voltages (V) in the legs' colours, over the replayed window; u3 dashed, u2
    thicker behind it, so that both show where they are equal (legs 2 and 3 mirror
    each other on a pitch or heave step). Text is
    :data:`TEXT_PX` pixels high at 640 px wide (:func:`text_px`).

    Returns
    -------
    image : ndarray (height, width, 3) uint8
    boxes : list of (x0, x1, y0, y1)
        Pixel extent of each panel's plotting area (where the cursor goes).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from simpro_mj.report.figures import DESIRED, LEG_COLOURS, OUTPUT, TASK_AXES, envelope

    dpi = 100.0
    fig = Figure(figsize=(width / dpi, height / dpi), dpi=dpi)
    canvas = FigureCanvasAgg(fig)
    c, t = rec.columns, rec.columns["time_s"]
    sel = (t >= t0 - 1e-9) & (t <= t1 + 1e-9)
    px = text_px(width, 2 * height)  # the strip is half a view high
    pt = px * 72.0 / dpi  # points of a px-pixel font
    axes = fig.subplots(1, 4)
    for ax, (title, ref, real, _m, scale, unit, zero) in zip(axes[:3], TASK_AXES, strict=True):
        ax.plot(*envelope(t[sel], (c[ref][sel] - zero) * scale), color=DESIRED,
                lw=1.0, ls="--", label="set-point (ghost)")  # fmt: skip
        ax.plot(*envelope(t[sel], (c[real][sel] - zero) * scale), color=OUTPUT,
                lw=1.2, label="pose")  # fmt: skip
        ax.set_title(f"{title.split(') ')[1].lower()} [{unit}]", fontsize=pt, pad=2)
    for i, lw, ls in ((1, 0.8, "-"), (2, 1.6, "-"), (3, 0.9, (0, (3, 2)))):
        axes[3].plot(*envelope(t[sel], c[f"u{i}_v"][sel]), color=LEG_COLOURS[i], lw=lw, ls=ls,
                     label=f"u{i}")  # fmt: skip
    axes[3].set_title("valves [V]", fontsize=pt, pad=2)
    # above the panels, where no curve runs
    handles, labels = axes[0].get_legend_handles_labels()
    h3, l3 = axes[3].get_legend_handles_labels()
    fig.legend(handles + h3, labels + l3, loc="upper center", ncol=5, fontsize=pt,
               frameon=False, handlelength=1.2, columnspacing=1.0, borderaxespad=0.1)  # fmt: skip
    for ax in axes:
        ax.set_xlim(t0, t1)
        ax.locator_params(nbins=3)
        ax.ticklabel_format(axis="y", useOffset=False)  # 3.0, not an offset +1e-3
        ax.tick_params(labelsize=pt, length=2, pad=1)
        ax.set_xlabel("t [s]", fontsize=pt, labelpad=1)
    # room for four-digit tick labels, x labels and the legend (within reach of a tiny strip)
    fig.subplots_adjust(left=min(3.6 * px / width, 0.2), right=0.99,
                        bottom=min(3.0 * px / height, 0.3), top=max(1.0 - 3.2 * px / height, 0.7),
                        wspace=0.55)  # fmt: skip
    canvas.draw()
    img = np.asarray(canvas.buffer_rgba())[..., :3].copy()
    boxes = []
    for ax in axes:
        (x0, y0), (x1, y1) = ax.get_window_extent().get_points()
        # figure pixels have y up; the image's rows go down
        boxes.append(
            (int(round(x0)), int(round(x1)), int(round(height - y1)), int(round(height - y0)))
        )
    return img, boxes


class TextStamp:
    """Short texts (the time overlay) pasted per frame from glyphs drawn once.

    matplotlib draws each character of :attr:`CHARS` once into a cell of
    ``px`` pixels' font; :meth:`stamp` pastes the cells of a text into a frame
    at the cost of a few array copies, white on a dark box.
    """

    CHARS = "0123456789.-+= tsdegpitchrolavmkx/:"

    def __init__(self, px: int = TEXT_PX):
        self.h = int(round(px * 1.5)) // 2 * 2
        self.w = int(round(px * 0.65))
        self.cells = {
            ch: _text_image(ch, self.w, self.h, px * 0.72, family="monospace")
            for ch in dict.fromkeys(self.CHARS)
        }

    def stamp(self, image: np.ndarray, text: str, right: int, top: int) -> np.ndarray:
        """Paste ``text`` into ``image`` (in place) ending at column ``right``, row ``top``."""
        cells = [self.cells.get(ch, self.cells[" "]) for ch in text]
        if not cells:
            return image
        row = np.concatenate(cells, axis=1)
        h, w = min(row.shape[0], image.shape[0] - top), min(row.shape[1], right)
        image[top : top + h, right - w : right] = row[:h, row.shape[1] - w :]
        return image


def label_image(text: str, height: int) -> np.ndarray:
    """A small white-on-dark RGB label (drawn once with matplotlib, pasted per frame)."""
    h = max(int(1.6 * TEXT_PX), int(height * 0.06)) // 2 * 2
    w = max(2 * h, int(0.62 * h * (len(text) + 1))) // 2 * 2
    return _text_image(text, w, h, h * 0.5)


def _text_image(text: str, w: int, h: int, fontsize: float, **font) -> np.ndarray:
    """``text`` white, centred on a dark ``w`` x ``h`` RGB image, drawn by matplotlib."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(w / 100.0, h / 100.0), dpi=100.0, facecolor=(0.1, 0.1, 0.12))
    canvas = FigureCanvasAgg(fig)
    fig.text(0.5, 0.5, text, color="white", ha="center", va="center", fontsize=fontsize, **font)
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].copy()


def draw_cursor(strip: np.ndarray, boxes, frac: float) -> np.ndarray:
    """A copy of the strip with a red time cursor at ``frac`` (0..1) of each panel."""
    out = strip.copy()
    for x0, x1, y0, y1 in boxes:
        x = int(round(x0 + frac * (x1 - x0)))
        x = min(max(x, x0), max(x1 - 1, x0))
        out[max(y0, 0) : y1, max(x - 1, 0) : x + 1] = (220, 30, 30)
    return out
