"""File IO: exact round trips and one-line errors that name the file."""

import numpy as np
import pytest

from freqbrdf.util.io import atomic_path, read_exr, read_json, read_png, write_exr, write_json, write_png
from freqbrdf.util.colour import tonemap, to_srgb


@pytest.mark.parametrize("shape", [(5, 7), (5, 7, 3), (5, 7, 4)])
def test_exr_round_trip_is_exact(tmp_path, shape):
    image = np.random.default_rng(0).uniform(0, 1e4, size=shape).astype(np.float32)
    write_exr(tmp_path / "a.exr", image)
    np.testing.assert_array_equal(read_exr(tmp_path / "a.exr"), image)


def test_exr_errors_name_the_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="missing.exr"):
        read_exr(tmp_path / "missing.exr")
    (tmp_path / "corrupt.exr").write_bytes(b"not an exr at all")
    with pytest.raises(ValueError, match="corrupt.exr.*not a readable OpenEXR"):
        read_exr(tmp_path / "corrupt.exr")
    with pytest.raises(ValueError, match="nan.exr.*refusing to write 1 NaN"):
        write_exr(tmp_path / "nan.exr", np.array([[0.0, np.nan]]))
    assert not (tmp_path / "nan.exr").exists()
    with pytest.raises(ValueError, match=r"shape \(2, 2, 2\)"):
        write_exr(tmp_path / "bad.exr", np.zeros((2, 2, 2)))


def test_exr_with_nan_pixels_is_rejected_on_read_unless_allowed(tmp_path):
    import OpenEXR

    image = np.ones((4, 4, 3), np.float32)
    image[1, 2, 0] = np.nan
    image[3, 3, 1] = np.inf
    with OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION}, {"RGB": image}) as f:
        f.write(str(tmp_path / "nan.exr"))
    with pytest.raises(ValueError, match="nan.exr: 2 NaN/Inf"):
        read_exr(tmp_path / "nan.exr")
    assert np.isnan(read_exr(tmp_path / "nan.exr", allow_nonfinite=True)).sum() == 1


def test_truncated_exr_is_reported(tmp_path):
    write_exr(tmp_path / "full.exr", np.ones((64, 64, 3), np.float32))
    data = (tmp_path / "full.exr").read_bytes()
    (tmp_path / "cut.exr").write_bytes(data[: len(data) // 2])
    with pytest.raises(ValueError, match="cut.exr"):
        read_exr(tmp_path / "cut.exr")


def test_atomic_path_leaves_nothing_behind_on_failure(tmp_path):
    target = tmp_path / "sub" / "out.txt"
    with pytest.raises(RuntimeError):
        with atomic_path(target) as tmp:
            tmp.write_text("half")
            raise RuntimeError("killed")
    assert not target.exists()
    assert list((tmp_path / "sub").iterdir()) == []


def test_png_and_json_round_trip(tmp_path):
    grey = np.linspace(0, 1, 256).reshape(16, 16)
    write_png(tmp_path / "g.png", grey)
    np.testing.assert_array_equal(read_png(tmp_path / "g.png"), np.round(grey * 255).astype(np.uint8))
    write_json(tmp_path / "c.json", {"a": [1, 2.5]})
    assert read_json(tmp_path / "c.json") == {"a": [1, 2.5]}
    (tmp_path / "bad.json").write_text("{")
    with pytest.raises(ValueError, match="bad.json: malformed JSON"):
        read_json(tmp_path / "bad.json")


def test_srgb_curve_and_tonemap_known_values():
    np.testing.assert_allclose(to_srgb(np.array([0.0, 0.0031308, 0.18, 1.0, 5.0])), [0.0, 0.04045, 0.46135, 1.0, 1.0], atol=1e-4)
    np.testing.assert_allclose(tonemap(np.array([4.0])), 1.0)  # white point
    assert tonemap(np.array([0.1]))[0] < tonemap(np.array([0.2]))[0] < 1.0


def test_atomic_directory_replaces_only_on_success(tmp_path):
    from freqbrdf.util.io import atomic_directory

    target = tmp_path / "capture"
    with atomic_directory(target) as tmp:
        (tmp / "a.txt").write_text("1")
    assert (target / "a.txt").read_text() == "1"
    with pytest.raises(RuntimeError):
        with atomic_directory(target) as tmp:
            (tmp / "b.txt").write_text("2")
            raise RuntimeError("interrupted")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["capture"]  # no partial directory left
    assert [p.name for p in target.iterdir()] == ["a.txt"]  # the old complete output is untouched


def test_atomic_path_creates_files_with_the_umask_mode(tmp_path):
    """mkstemp's owner-only mode would make every output unreadable to a cluster's other users."""
    import os

    from freqbrdf.util.io import atomic_path

    old = os.umask(0o022)
    try:
        with atomic_path(tmp_path / "out.txt") as tmp:
            tmp.write_text("x")
    finally:
        os.umask(old)
    assert (tmp_path / "out.txt").stat().st_mode & 0o777 == 0o644
    assert [p.name for p in tmp_path.iterdir()] == ["out.txt"]


def test_progress_extrapolates_the_time_left():
    from freqbrdf.util.logs import progress

    assert progress(3, 24, 2.1) == "3 of 24, 2.1 s elapsed, about 15 s left"  # 0.7 s each, 21 to go
    assert progress(24, 24, 16.8).endswith("about 0 s left")


def test_a_second_writer_of_an_output_is_refused_until_the_first_dies(tmp_path):
    """writer_lock: while one process writes an output another stops, naming it; a SIGKILLed
    writer leaves the lock free (the kernel drops it), and a clean exit leaves no lock file."""
    import subprocess
    import sys
    import time

    from freqbrdf.util.io import WriterLockError, atomic_directory

    out = tmp_path / "capture"
    first = subprocess.Popen([sys.executable, "-c", "import sys, time; from freqbrdf.util.io import atomic_directory\n"
                              f"with atomic_directory({str(out)!r}) as tmp:\n    print('in', flush=True); time.sleep(600)"],
                             stdout=subprocess.PIPE, text=True)
    try:
        assert first.stdout.readline().strip() == "in"
        with pytest.raises(WriterLockError, match=rf"capture: another process \(pid {first.pid} on .+\) is writing it"):
            with atomic_directory(out):
                pass
        assert (tmp_path / ".capture.partial").is_dir()  # the first writer's files are left alone
    finally:
        first.kill()
        first.wait()
    time.sleep(0.1)
    with atomic_directory(out) as tmp:  # the dead writer's lock is gone; its partial directory is redone
        assert not any(tmp.iterdir())
        (tmp / "a.txt").write_text("a")
    assert (out / "a.txt").read_text() == "a"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["capture"]


def test_an_output_is_not_moved_into_place_while_its_manifest_is_incomplete(tmp_path):
    """A capture whose cameras.json lists a view with no image fails before its rename."""
    from freqbrdf.scene.cameras import check_capture_files
    from freqbrdf.util.io import atomic_directory, write_json

    frames = [{"name": n, "image": f"images/{n}.exr", "mask": f"masks/{n}.png"} for n in ("000", "001")]
    with pytest.raises(ValueError, match=r"cameras.json lists 2 views, but 1 of their 4 images and masks are "
                                         r"missing \(first: images/001.exr\)"):
        with atomic_directory(tmp_path / "train", complete=check_capture_files) as tmp:
            for name in ("images/000.exr", "masks/000.png", "masks/001.png"):
                (tmp / name).parent.mkdir(exist_ok=True)
                (tmp / name).write_bytes(b"x")
            write_json(tmp / "cameras.json", {"frames": frames})
    assert list(tmp_path.iterdir()) == []  # neither the output nor its partial directory
