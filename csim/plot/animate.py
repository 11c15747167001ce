"""The mechanism moving: an animation of one run, drawn from the mechanism's geometry.

GIF through Pillow (a dependency of matplotlib), MP4 through ffmpeg when it is on the
PATH. Frames
are output samples of the run, spaced evenly in time; the time is shown on each frame.
"""
from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path

import matplotlib
import numpy as np
from matplotlib.animation import FFMpegWriter, writers
from PIL import Image

from csim.io.atomic import atomic_path
from csim.plot.drawing import MechanismArtists, geometry, setup_axes, symbol_size
from csim.plot.errors import PlotError, check_dpi
from csim.plot.source import COMPARISON, RunData, file_kind, load_run
from csim.plot.style import RC, SIZE, new_figure, title

#: animation file suffixes
ANIMATION_FORMATS = (".gif", ".mp4")

#: the most frames ``--max-frames`` may ask for: 50 s of animation at 20 fps; about 40 s
#: and 1 GB to write as a GIF at 100 dpi on a small machine
MAX_FRAMES = 1000
#: the most pixels of all frames together: MAX_FRAMES frames of the tallest figure (6.4 x
#: 7.68 in) at 100 dpi. A GIF holds every frame in memory until it is written (about two
#: bytes a pixel), so a higher ``--dpi`` allows fewer frames
MAX_ANIMATION_PIXELS = MAX_FRAMES * 640 * 768


def check_frames(fps: float, speed: float, max_frames: int) -> None:
    """Raise :class:`PlotError` naming the option unless ``fps`` > 0, ``speed`` > 0 and
    2 <= ``max_frames`` <= :data:`MAX_FRAMES`."""
    if not 0 < fps < math.inf:
        raise PlotError(f"--fps: got {fps:g}; expected a finite number of frames per second, fps > 0")
    if not 0 < speed < math.inf:
        raise PlotError(f"--speed: got {speed:g}; expected a finite number of simulated seconds per second, "
                        f"speed > 0")
    if not 2 <= max_frames <= MAX_FRAMES:
        raise PlotError(f"--max-frames: got {max_frames}; expected a whole number from 2 to {MAX_FRAMES:,} (a "
                        f"longer run is played faster to fit)")


def ffmpeg_available() -> bool:
    """Whether matplotlib finds ffmpeg (needed for MP4)."""
    return writers.is_available("ffmpeg")


def frame_times(t: np.ndarray, fps: float, speed: float, max_frames: int) -> tuple[np.ndarray, float]:
    """Times of the frames and the playback speed they give.

    Parameters
    ----------
    t : ndarray (N,)
        Output times of the run [s], increasing.
    fps : float
        Frames per second of the animation.
    speed : float
        Simulated seconds per second of animation (1: real time).
    max_frames : int
        At most this many frames; a longer run is played faster.

    Returns
    -------
    times : ndarray (F,) [s]
        Evenly spaced from t[0] to t[-1] (the last frame at t[-1] when it fits).
    speed : float
        The playback speed after the limits: raised when the output samples are coarser
        than the frame spacing, or when the frames would exceed ``max_frames``.
    """
    if t.size < 2 or not t[-1] > t[0] or not math.isfinite(float(t[-1] - t[0])):
        return t[:1].copy(), speed
    duration = float(t[-1] - t[0])
    spacing = speed / fps
    dt = float(np.median(np.diff(t)))
    spacing = max(spacing, dt)
    if duration / spacing + 1 > max_frames:
        spacing = duration / (max_frames - 1)
    n = min(int(math.floor(duration / spacing + 1e-9)) + 1, max_frames)
    return t[0] + spacing * np.arange(n), spacing * fps


def nearest_samples(t: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Index of the output sample nearest to each of ``times`` (distinct, increasing)."""
    i = np.clip(np.searchsorted(t, times), 0, t.size - 1)
    prev = np.clip(i - 1, 0, t.size - 1)
    i = np.where(np.abs(t[prev] - times) <= np.abs(t[i] - times), prev, i)
    return np.unique(i)


class MechanismAnimation:
    """An animation of one run: a figure and the frames that move it.

    Parameters
    ----------
    run : RunData
    fps : float
        Frames per second.
    speed : float
        Simulated seconds per second of animation (1: real time); see :func:`frame_times`.
    max_frames : int
    width : float
        Figure width [inch].

    Attributes
    ----------
    figure : Figure
    frames : ndarray (F,) of int
        The output sample shown in each frame.
    speed : float
        Playback speed after the limits.
    points : ndarray (F, P, dim)
        The drawing's points in each frame [m].
    """

    def __init__(self, run: RunData, fps: float = 20.0, speed: float = 1.0, max_frames: int = 300,
                 width: float = SIZE[0]):
        check_frames(fps, speed, max_frames)
        res = run.result
        if run.definition is None:
            why = run.unavailable or f"mechanism {res.mechanism!r} is not known to this csim"
            raise PlotError(f"{run.path}: {why}; cannot draw it")
        self.run, self.fps = run, fps
        self.geometry = geometry(run.definition, run.parameters)
        finite = np.flatnonzero(np.all(np.isfinite(res.q), axis=1) & np.isfinite(res.t))
        if finite.size == 0:
            raise PlotError(f"{run.path}: the run has no finite sample to animate")
        times, self.speed = frame_times(res.t[finite], fps, speed, max_frames)
        self.frames = finite[nearest_samples(res.t[finite], times)]
        self.points = self.geometry.points(res.q[self.frames])
        lo, hi = self.geometry.bounds(self.points)
        scale = symbol_size(lo, hi)
        lo, hi = self.geometry.bounds(self.points, scale)
        with matplotlib.rc_context(RC):
            if self.geometry.dim == 2:
                span = np.maximum(hi - lo, 1e-9)
                height = min(max(width * span[1] / span[0] + 1.3, 2.5), 1.2 * width)
                fig, axes = new_figure(1, 1, width=width, height=height)
            else:
                fig, axes = new_figure(1, 1, width=width, height=0.85 * width, projection="3d")
            ax = axes[0, 0]
            self.artists = MechanismArtists(ax, self.geometry, self.points[0], scale)
            setup_axes(ax, self.geometry, lo, hi)
            if self.geometry.dim == 2:  # the limits give way, not the box: the labels stay inside the frame
                ax.set_xlim(auto=True)  # either may give way: matplotlib warns when the one it widens is fixed
                ax.set_ylim(auto=True)
                ax.set_aspect("equal", adjustable="datalim")
            place = ax.text2D if self.geometry.dim == 3 else ax.text
            self.clock = place(0.02, 0.97, "", transform=ax.transAxes, va="top", ha="left",
                               fontfamily="monospace", bbox=dict(facecolor="white", edgecolor="none", alpha=0.8))
            playback = "real time" if math.isclose(self.speed, 1.0, rel_tol=1e-6) else f"{self.speed:.3g}x real time"
            title(fig, f"The {res.mechanism.replace('_', '-')} mechanism in motion",
                  f"{run.describe()}; played at {playback}")
        self.figure = fig
        self.update(0)

    def __len__(self) -> int:
        return int(self.frames.size)

    def check_size(self, dpi: float) -> None:
        """Raise :class:`PlotError` when the frames at ``dpi`` exceed :data:`MAX_ANIMATION_PIXELS`."""
        width, height = (round(x * dpi) for x in self.figure.get_size_inches())
        total = len(self) * width * height
        if total > MAX_ANIMATION_PIXELS:
            fits = MAX_ANIMATION_PIXELS // max(width * height, 1)
            advice = (f"--max-frames {fits} or fewer at this --dpi, or a lower --dpi" if fits >= 2 else
                      "a lower --dpi")
            raise PlotError(f"--max-frames / --dpi: {len(self)} frames of {width} x {height} pixels at --dpi {dpi:g} "
                            f"make {total:.3g} pixels; expected at most {MAX_ANIMATION_PIXELS:.3g} (a GIF holds "
                            f"every frame in memory); give {advice}")

    def update(self, frame: int) -> list:
        """Show frame ``frame``; returns the artists it changed."""
        changed = self.artists.update(self.points[frame])
        self.clock.set_text(f"t = {self.run.result.t[self.frames[frame]]:.3f} s")
        return [*changed, self.clock]

    @property
    def moving(self) -> list:
        """The artists that change from frame to frame."""
        return [*self.artists.links, self.artists.joints, self.clock]

    def frames_rgb(self, dpi: float = 100) -> Iterator[np.ndarray]:
        """The frames as images, drawn by blitting (the still parts are drawn once).

        Yields
        ------
        ndarray (H, W, 3) of uint8
        """
        fig, canvas = self.figure, self.figure.canvas
        fig.set_dpi(dpi)
        moving = self.moving
        for artist in moving:
            artist.set_animated(True)
        try:
            with matplotlib.rc_context(RC):
                canvas.draw()  # the layout, and everything that stays
                background = canvas.copy_from_bbox(fig.bbox)
                for i in range(len(self)):
                    canvas.restore_region(background)
                    for artist in self.update(i):
                        fig.draw_artist(artist)
                    yield np.asarray(canvas.buffer_rgba())[..., :3].copy()
        finally:
            for artist in moving:
                artist.set_animated(False)

    def save(self, path: str | Path, dpi: float = 100) -> Path:
        """Write the animation to ``path`` (``.gif``, or ``.mp4`` with ffmpeg), atomically.

        Raises
        ------
        PlotError
            For another suffix, MP4 without ffmpeg, a bad ``dpi``, or a path that cannot be
            written.
        """
        path = Path(path)
        suffix = path.suffix.lower()
        if suffix not in ANIMATION_FORMATS:
            raise PlotError(f"--output {path}: unknown animation format {suffix or '(no suffix)'!r}; "
                            f"valid: {', '.join(ANIMATION_FORMATS)}")
        check_dpi(dpi)
        if suffix == ".gif":  # a GIF holds every frame in memory; ffmpeg takes an MP4's one at a time
            self.check_size(dpi)
        if suffix == ".mp4" and not ffmpeg_available():
            raise PlotError(f"--output {path}: MP4 needs ffmpeg, which is not on the PATH; "
                            f"write a GIF instead (-o {path.with_suffix('.gif')})")
        if path.is_dir():
            raise PlotError(f"--output {path}: cannot write, it is a directory")
        started = False  # (an error before the writer ran: the folder or the temporary file)
        try:
            with atomic_path(path) as tmp:  # written whole or not at all, a symbolic link replaced
                started = True
                (self._write_gif if suffix == ".gif" else self._write_mp4)(str(tmp), dpi)
        except OSError as exc:
            if not started:
                raise PlotError(f"--output {path}: cannot write there ({exc.strerror or exc})") from None
            raise PlotError(f"cannot write {path}: {exc.strerror or exc}") from None
        return path

    def _write_gif(self, path: str, dpi: float) -> None:
        # the first frame's adaptive palette for every frame: it holds the links' colours
        # exactly (each link is in every frame), and mapping a frame to a given palette takes
        # a fifteenth of the time of making one for it
        images: list[Image.Image] = []
        for rgb in self.frames_rgb(dpi):
            frame = Image.fromarray(rgb)
            if not images:
                images.append(frame.convert("P", palette=Image.Palette.ADAPTIVE, colors=256))
            else:
                images.append(frame.quantize(palette=images[0], dither=Image.Dither.NONE))
        images[0].save(path, format="GIF", save_all=True, append_images=images[1:],
                       duration=round(1000 / self.fps), loop=0, disposal=1)

    def _write_mp4(self, path: str, dpi: float) -> None:
        writer = FFMpegWriter(fps=self.fps, codec="libx264", extra_args=["-pix_fmt", "yuv420p"])
        with matplotlib.rc_context(RC), writer.saving(self.figure, path, dpi):
            for i in range(len(self)):
                self.update(i)
                writer.grab_frame()


def animate_file(path: str | Path, output: str | Path, group: str | None = None, fps: float = 20.0,
                 speed: float = 1.0, max_frames: int = 300, dpi: float = 100) -> MechanismAnimation:
    """Animate the run in ``path`` (a method group of a comparison file with ``group``) into
    ``output`` (``.gif`` or ``.mp4``).

    Returns
    -------
    MechanismAnimation
        The animation written (its ``frames`` and ``speed`` say what was shown).

    Raises
    ------
    ResultFileError
        Missing or unreadable file, or a missing group.
    PlotError
        A comparison file without ``group``, a run without samples, a mechanism without a
        drawing, a bad output format or an unwritable output.
    """
    output = Path(output)
    if output.suffix.lower() not in ANIMATION_FORMATS:
        raise PlotError(f"--output {output}: unknown animation format {output.suffix or '(no suffix)'!r}; "
                        f"valid: {', '.join(ANIMATION_FORMATS)}")
    check_dpi(dpi)
    check_frames(fps, speed, max_frames)
    if file_kind(path) == COMPARISON and not group:
        from csim.io.hdf5 import read_comparison

        methods = read_comparison(path).methods
        raise PlotError(f"{path} is a comparison file with one run per method; choose one with --group NAME, "
                        f"NAME one of {', '.join([*methods, 'reference'])}")
    run = load_run(path, group)
    if run.result.t.size == 0:
        raise PlotError(f"{path}: the run has no samples to animate (status {run.result.status}: "
                        f"{run.result.message})")
    animation = MechanismAnimation(run, fps=fps, speed=speed, max_frames=max_frames)
    animation.save(output, dpi=dpi)
    return animation
