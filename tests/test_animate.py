"""``csim animate``: the mechanism moving, its frames drawn from the HDF5 data, GIF output,
2-D and 3-D drawings, and clear errors (exit code 2)."""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import h5py
import numpy as np
import pytest
import sympy as sp
from conftest import assert_bad_input, invoke, simulated_file
from PIL import Image

from csim.compare import compare
from csim.mechanisms import get_mechanism
from csim.model.definition import Drawing
from csim.plot import MechanismAnimation, PlotError, animate_file
from csim.plot import animate as animate_module
from csim.plot.animate import frame_times, nearest_samples
from csim.plot.drawing import geometry
from csim.plot.run_figures import snapshots_figure
from csim.plot.source import load_run

CONFIGS = Path(__file__).resolve().parents[1] / "configs"


@pytest.fixture(scope="module")
def qr_file(tmp_path_factory):
    return simulated_file(tmp_path_factory, "quick_return.yaml", "qr.h5", "simulation.t_end=0.2")


@pytest.fixture(scope="module")
def pendulum_file(tmp_path_factory):
    return simulated_file(tmp_path_factory, "pendulum.yaml", "pendulum.h5", "simulation.t_end=0.4")


def read(path, name, group="/"):
    with h5py.File(path, "r") as fh:
        return fh[group][name][()]


def by_gid(fig, gid):
    (artist,) = fig.findobj(lambda a: a.get_gid() == gid)
    return artist


# --------------------------------------------------------------------------- frames


def test_frame_times_real_time_and_limits():
    t = np.linspace(0.0, 2.0, 401)  # output every 5 ms
    times, speed = frame_times(t, fps=20, speed=1.0, max_frames=300)
    np.testing.assert_allclose(times, np.arange(41) * 0.05, atol=1e-12)
    assert speed == pytest.approx(1.0)
    times, speed = frame_times(t, fps=20, speed=1.0, max_frames=11)  # too many frames: played faster
    assert times.size == 11 and times[-1] == pytest.approx(2.0) and speed == pytest.approx(4.0)
    coarse = np.linspace(0.0, 2.0, 11)  # output coarser than the frame spacing
    times, speed = frame_times(coarse, fps=20, speed=1.0, max_frames=300)
    assert times.size == 11 and speed == pytest.approx(4.0)
    np.testing.assert_array_equal(nearest_samples(t, np.array([0.0, 0.0049, 0.0051, 2.1])), [0, 1, 400])


def test_gif_of_the_quick_return_mechanism(qr_file, tmp_path):
    out = tmp_path / "qr.gif"
    result = invoke("animate", qr_file, "-o", out, "--dpi", "50", "--speed", "0.5")
    assert result.exit_code == 0, result.output
    with Image.open(out) as im:
        assert im.format == "GIF"
        n = im.n_frames
        assert im.info["duration"] == 50 and im.size[0] == 320
    # 0.2 s at half speed and 20 fps: a frame every 25 ms
    assert n == 9 and "9 frames" in result.output and "0.5x real time" in result.output


def test_frames_draw_the_hdf5_configuration(qr_file):
    run = load_run(qr_file)
    anim = MechanismAnimation(run, fps=20, speed=0.5)
    t, q = read(qr_file, "t"), read(qr_file, "q")
    d = get_mechanism("quick_return")
    l1, l2, h1, h2 = (d.parameter(n).default for n in ("l1", "l2", "h1", "h2"))
    assert len(anim) == 9
    np.testing.assert_allclose(t[anim.frames], np.arange(9) * 0.025, atol=1e-12)
    for k in range(len(anim)):
        anim.update(k)
        i = anim.frames[k]
        crank = by_gid(anim.figure, "link:O-A").get_xydata()
        np.testing.assert_allclose(crank, [[0, h1], [l1 * math.cos(q[i, 0]), h1 + l1 * math.sin(q[i, 0])]],
                                   atol=1e-12)
        rocker = by_gid(anim.figure, "link:B-C").get_xydata()
        np.testing.assert_allclose(rocker[1], [l2 * math.cos(q[i, 1]), l2 * math.sin(q[i, 1])], atol=1e-12)
        rod = by_gid(anim.figure, "link:C-D").get_xydata()
        np.testing.assert_allclose(rod[1], [read(qr_file, "observables/ram_x")[i], h2], atol=1e-9)
        assert anim.clock.get_text() == f"t = {t[i]:.3f} s"


def test_blitted_frames_change_and_match_a_full_redraw(pendulum_file):
    anim = MechanismAnimation(load_run(pendulum_file), fps=10)
    frames = list(anim.frames_rgb(dpi=40))
    assert len(frames) == len(anim) and frames[0].ndim == 3
    assert not np.array_equal(frames[0], frames[-1])
    anim.update(len(anim) - 1)
    anim.figure.canvas.draw()
    full = np.asarray(anim.figure.canvas.buffer_rgba())[..., :3]
    assert np.mean(np.any(full != frames[-1], axis=2)) < 0.01  # the same picture, up to antialiasing


def test_pendulum_bob_follows_q(pendulum_file):
    anim = MechanismAnimation(load_run(pendulum_file), fps=10)
    q = read(pendulum_file, "q")
    for k in (0, len(anim) - 1):
        anim.update(k)
        np.testing.assert_allclose(by_gid(anim.figure, "link:pivot-bob").get_xydata(), [[0, 0], q[anim.frames[k]]],
                                   atol=1e-15)
        joints = by_gid(anim.figure, "joints").get_xydata()
        np.testing.assert_allclose(joints[1], q[anim.frames[k]], atol=1e-15)


def test_comparison_group_is_animated(tmp_path):
    c = compare(CONFIGS / "pendulum.yaml", methods=["baumgarte"], overrides=["simulation.t_end=0.1"], jobs=1)
    path = tmp_path / "cmp.h5"
    c.write(path)
    assert_bad_input(invoke("animate", path, "-o", tmp_path / "a.gif"), "comparison file", "--group",
                     "baumgarte, reference")
    anim = animate_file(path, tmp_path / "a.gif", group="baumgarte", fps=10, dpi=30)
    assert (tmp_path / "a.gif").is_file() and len(anim) == 2


# --------------------------------------------------------------------------- 3-D drawings


def spatial_pendulum_run(pendulum_file):
    """The pendulum's run with a 3-D drawing: the bob lifted out of the plane by z = x y."""
    run = load_run(pendulum_file)
    d = run.definition
    x, y = d.coordinates
    L = d.parameter_symbols[1]
    drawing = Drawing(points={"pivot": (sp.Integer(0), sp.Integer(0), sp.Integer(0)), "bob": (x, y, x * y),
                              "tip": (x, y, x * y + L / 4), "foot": (x / 2, y / 2, sp.Integer(0))},
                      links=[("pivot", "bob"), ("bob", "tip", "foot")], ground=["pivot"],
                      guides=[((-L, 0, 0), (L, 0, 0))])
    return dataclasses.replace(run, definition=dataclasses.replace(d, drawing=drawing))


def test_3d_drawing_is_evaluated_and_animated(pendulum_file, tmp_path):
    run = spatial_pendulum_run(pendulum_file)
    q = read(pendulum_file, "q")
    geom = geometry(run.definition, run.parameters)
    assert geom.dim == 3 and geom.guides.shape == (1, 2, 3)
    np.testing.assert_allclose(geom.points(q[5])[1], [q[5, 0], q[5, 1], q[5, 0] * q[5, 1]])
    anim = MechanismAnimation(run, fps=10)
    assert anim.figure.axes[0].name == "3d"
    anim.update(2)
    xs, ys, zs = by_gid(anim.figure, "link:pivot-bob").get_data_3d()
    bob = q[anim.frames[2]]
    np.testing.assert_allclose(np.column_stack((xs, ys, zs)), [[0, 0, 0], [bob[0], bob[1], bob[0] * bob[1]]])
    assert anim.figure.axes[0].get_zlabel() == "z [m]"
    out = anim.save(tmp_path / "spatial.gif", dpi=30)
    with Image.open(out) as im:
        assert im.n_frames == len(anim)


def test_3d_snapshots(pendulum_file):
    run = spatial_pendulum_run(pendulum_file)
    fig = snapshots_figure(run, 3)
    axes = [ax for ax in fig.axes if ax.get_visible()]
    assert len(axes) == 3 and all(ax.name == "3d" for ax in axes)


def test_mixed_drawing_dimensions_are_rejected(pendulum_file):
    run = load_run(pendulum_file)
    x, y = run.definition.coordinates
    bad = Drawing(points={"pivot": (sp.Integer(0), sp.Integer(0)), "bob": (x, y, sp.Integer(0))},
                  links=[("pivot", "bob")])
    with pytest.raises(PlotError, match=r"must all be \(x, y\) or all \(x, y, z\)"):
        geometry(dataclasses.replace(run.definition, drawing=bad), run.parameters)
    with pytest.raises(PlotError, match="declares no drawing"):
        geometry(dataclasses.replace(run.definition, drawing=None), run.parameters)


# --------------------------------------------------------------------------- errors


def test_cli_animate_errors(qr_file, tmp_path, monkeypatch):
    assert_bad_input(invoke("animate", tmp_path / "missing.h5", "-o", tmp_path / "a.gif"), "no such result file")
    text = tmp_path / "text.h5"
    text.write_text("hello")
    assert_bad_input(invoke("animate", text, "-o", tmp_path / "a.gif"), "not a readable HDF5 file")
    assert_bad_input(invoke("animate", qr_file, "-o", tmp_path / "a.avi"), "unknown animation format '.avi'",
                     ".gif, .mp4")
    assert_bad_input(invoke("animate", qr_file, "-o", tmp_path / "a.gif", "--fps", "0"), "fps > 0")
    assert_bad_input(invoke("animate", qr_file, "-o", tmp_path / "a.gif", "--dpi", "-1"), "--dpi")
    assert_bad_input(invoke("animate", qr_file, "-o", tmp_path), "unknown animation format")
    monkeypatch.setattr(animate_module, "ffmpeg_available", lambda: False)
    assert_bad_input(invoke("animate", qr_file, "-o", tmp_path / "a.mp4"), "MP4 needs ffmpeg", "a.gif")
    assert not list(tmp_path.glob("*.gif")) and not list(tmp_path.glob(".*"))


@pytest.mark.skipif(not animate_module.ffmpeg_available(), reason="ffmpeg is not installed")
def test_mp4_with_ffmpeg(pendulum_file, tmp_path):
    anim = animate_file(pendulum_file, tmp_path / "p.mp4", fps=10, dpi=30)
    assert (tmp_path / "p.mp4").stat().st_size > 0 and len(anim) > 1


def test_labels_and_title_lie_inside_the_frame(qr_file):
    anim = MechanismAnimation(load_run(qr_file), fps=20)
    fig = anim.figure
    next(anim.frames_rgb(dpi=100))  # lays the figure out as the file's frames are
    renderer = fig.canvas.get_renderer()
    frame = fig.bbox
    ax = fig.axes[0]
    for text in (ax.xaxis.label, ax.yaxis.label, *fig.texts):
        if text.get_text():
            box = text.get_window_extent(renderer)
            assert frame.x0 - 1 <= box.x0 and box.x1 <= frame.x1 + 1, text.get_text()
            assert frame.y0 - 1 <= box.y0 and box.y1 <= frame.y1 + 1, text.get_text()


@pytest.mark.parametrize("which", ["qr_file", "pendulum_file"])
def test_frames_draw_without_matplotlib_warnings(which, request, caplog):
    """A wide drawing (the quick-return) and a tall one (the pendulum): the equal aspect widens
    the limits that may give way, without matplotlib's logged "Ignoring fixed ... limits"."""
    anim = MechanismAnimation(load_run(request.getfixturevalue(which)), fps=10)
    with caplog.at_level("WARNING"):
        anim.update(1)
        anim.figure.canvas.draw()
    assert not [r.getMessage() for r in caplog.records], [r.getMessage() for r in caplog.records]
