"""numpy's OpenBLAS runs one thread while a frame is made, and gets its own count back after."""
import numpy as np
import pytest

from addon.gpu.blas import one_blas_thread, openblas_threads


def test_one_thread_inside_the_block_and_the_old_count_after():
    before = openblas_threads()
    if not before:
        pytest.skip("this numpy has no OpenBLAS of its own")
    with one_blas_thread():
        assert openblas_threads() == [1] * len(before)
        m = np.diag([2.0, 4.0, 8.0, 1.0])
        assert np.allclose(np.linalg.inv(m) @ m, np.eye(4))
    assert openblas_threads() == before


def test_the_count_comes_back_when_the_block_raises():
    before = openblas_threads()
    with pytest.raises(RuntimeError):
        with one_blas_thread():
            raise RuntimeError("a frame that fails")
    assert openblas_threads() == before


@pytest.fixture
def probe():
    """A stand-in for what a frame calls first: it notes OpenBLAS's thread counts there and stops the frame.
    After the test the counts must be back."""
    before = openblas_threads()
    if not before:
        pytest.skip("this numpy has no OpenBLAS of its own")

    def stop(*args, **kwargs):
        stop.seen.append(openblas_threads())
        raise RuntimeError("stop once inside")
    stop.seen, stop.one = [], [1] * len(before)
    yield stop
    assert openblas_threads() == before


def test_render_shadows_makes_its_frame_with_one_thread(monkeypatch, probe):
    from addon.gpu import pipeline
    monkeypatch.setattr(pipeline, "ShadowFrame", probe)
    setup = type("Setup", (), {"maps": [object()]})()
    with pytest.raises(RuntimeError):
        pipeline.render_shadows(None, None, setup, None)
    assert probe.seen == [probe.one]


def test_the_viewport_computes_and_draws_with_one_thread(monkeypatch, probe):
    """The sidebar's live update (the warp) and the picture-in-picture frame hold the same limit as F12."""
    from addon.gpu import context
    from addon.ui import live, renders
    monkeypatch.setattr(live, "LiveState", probe)
    monkeypatch.setattr(context, "ensure_gpu_context", probe)
    with pytest.raises(RuntimeError):
        live.update(type("Scene", (), {"name": "lixel_blas_probe", "session_uid": -1})())
    with pytest.raises(RuntimeError):
        renders.pip_textures(None, None, 64, want_map=True, want_scene=False)
    assert probe.seen == [probe.one] * 2
