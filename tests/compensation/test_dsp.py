import numpy as np
import pytest
from scipy.signal import butter

from aeromag_env.compensation.dsp import bandpass, bandpass_finite, highpass, lowpass, min_length
from aeromag_env.errors import AeromagError
from tests._helpers import assert_one_line_error

FS = 10.0  # [Hz], the SGL / simulator rate


def _amplitude(y: np.ndarray, f_hz: float, fs_hz: float) -> float:
    """Amplitude of the f_hz component of y by projection (y spans whole cycles)."""
    t = np.arange(y.size) / fs_hz
    c, s = np.cos(2 * np.pi * f_hz * t), np.sin(2 * np.pi * f_hz * t)
    return float(np.hypot(2 * np.mean(y * c), 2 * np.mean(y * s)))


def _butterworth_gain(f_hz: float, fc_hz: float, fs_hz: float, order: int, kind: str) -> float:
    """Amplitude gain of forward–backward filtering with a digital Butterworth of order n.

    One pass has amplitude gain |H| with |H|² = 1 / (1 + (f/fc)^(2n)); two passes (filtfilt)
    multiply the amplitude by |H| twice, i.e. by |H|².

    scipy designs by the bilinear transform, which maps the analog frequency to
    tan(π f / fs); with that warping the closed form is exact (analog f/fc would be off by ~10 %
    at 2 Hz / 1 Hz and 10 Hz sampling).
    """
    ratio = np.tan(np.pi * f_hz / fs_hz) / np.tan(np.pi * fc_hz / fs_hz)
    ratio = ratio if kind == "low" else 1.0 / ratio
    return float(1.0 / (1.0 + ratio ** (2 * order)))


def test_sinusoid_inside_band_passes_within_one_percent():
    t = np.arange(6000) / FS  # 600 s, whole cycles of 0.4 Hz
    x = 3.0 * np.sin(2 * np.pi * 0.4 * t + 0.3)
    y = bandpass(x, FS, 0.1, 0.9)
    inner = slice(1000, 5000)  # away from the edge transients (decay ≪ 100 s at 0.1 Hz)
    # 1 %: the 0.4 Hz gain of the 0.1–0.9 Hz 4-pole band is 1 − O(1e-3)
    assert _amplitude(y[inner], 0.4, FS) == pytest.approx(3.0, rel=0.01)
    # zero phase: the output lies on the input sample by sample (0.03 nT = 1 % of 3)
    np.testing.assert_allclose(y[inner], x[inner], atol=0.03)


@pytest.mark.parametrize(("kind", "f_hz", "fc_hz"), [("low", 2.0, 1.0), ("high", 0.5, 1.0)])
def test_outside_band_attenuated_by_butterworth_response_squared(kind, f_hz, fc_hz):
    t = np.arange(4000) / FS  # whole cycles of 2 Hz and 0.5 Hz
    x = np.sin(2 * np.pi * f_hz * t)
    y = lowpass(x, FS, fc_hz) if kind == "low" else highpass(x, FS, fc_hz)
    expected = _butterworth_gain(f_hz, fc_hz, FS, 4, kind)
    assert expected < 0.01  # really outside the band
    # 1 % relative: the steady-state response of a linear filter is exact; edges are cut
    assert _amplitude(y[500:3500], f_hz, FS) == pytest.approx(expected, rel=0.01)


def test_magnav_edge_conventions():
    x = np.random.default_rng(0).normal(size=(500, 2))
    np.testing.assert_array_equal(bandpass(x, FS, 0.0, 1.0), lowpass(x, FS, 1.0))
    np.testing.assert_array_equal(bandpass(x, FS, -1.0, 1.0), lowpass(x, FS, 1.0))
    np.testing.assert_array_equal(bandpass(x, FS, 1.0, FS / 2), highpass(x, FS, 1.0))
    np.testing.assert_array_equal(bandpass(x, FS, 1.0, 99.0), highpass(x, FS, 1.0))
    none = bandpass(x, FS, 0.0, FS / 2)
    np.testing.assert_array_equal(none, x)
    assert none is not x and not np.shares_memory(none, x)


def test_matches_scipy_sosfiltfilt_per_column():
    from scipy.signal import sosfiltfilt

    x = np.random.default_rng(1).normal(size=(800, 3))
    sos = butter(4, [0.1, 0.9], btype="bandpass", fs=FS, output="sos")
    # 1e-12 [same unit as x]: same arithmetic, column by column vs all columns at once
    np.testing.assert_allclose(bandpass(x, FS, 0.1, 0.9), sosfiltfilt(sos, x, axis=0), atol=1e-12)


def test_linear():
    rng = np.random.default_rng(2)
    x, z = rng.normal(size=1000), rng.normal(size=1000)
    y = bandpass(x, FS, 0.1, 0.9)
    # 1e-10 [unit of x]: a linear filter (edge padding included) up to rounding
    np.testing.assert_allclose(
        bandpass(2 * x - 3 * z, FS, 0.1, 0.9), 2 * y - 3 * bandpass(z, FS, 0.1, 0.9), atol=1e-10
    )


def test_constant_columns_left_unchanged():
    rng = np.random.default_rng(3)
    x = np.column_stack([rng.normal(size=400), np.full(400, 7.5), rng.normal(size=400)])
    y = bandpass(x, FS, 0.1, 0.9)
    np.testing.assert_array_equal(y[:, 1], 7.5)  # MagNav skips constant columns
    np.testing.assert_array_equal(y[:, 0], bandpass(x[:, 0], FS, 0.1, 0.9))
    np.testing.assert_array_equal(highpass(np.full(100, 3.0), FS, 0.5), 3.0)


def test_highpass_removes_offset():
    t = np.arange(3000) / FS
    y = highpass(100.0 + np.sin(2 * np.pi * 1.0 * t), FS, 0.05)
    # 1e-3 [unit of x]: the 100 offset is gone away from the edges; the 1 Hz tone averages out
    assert abs(np.mean(y[500:2500])) < 1e-3


def test_bandpass_finite_filters_each_run():
    rng = np.random.default_rng(4)
    x = rng.normal(size=300)
    x[100] = np.nan
    x[290:] = np.inf  # a run too short to filter
    y = bandpass_finite(x, FS, 0.1, 0.9)
    np.testing.assert_array_equal(y[:100], bandpass(x[:100], FS, 0.1, 0.9))
    np.testing.assert_array_equal(y[101:290], bandpass(x[101:290], FS, 0.1, 0.9))
    assert np.isnan(y[100]) and np.all(np.isnan(y[290:]))


def test_errors_are_one_line():
    x = np.ones(500)
    x[3] = np.nan
    with pytest.raises(AeromagError, match="non-finite") as e:
        bandpass(x, FS, 0.1, 0.9)
    assert_one_line_error(e)
    sos = butter(4, [0.1, 0.9], btype="bandpass", fs=FS, output="sos")
    with pytest.raises(AeromagError, match="too short") as e:
        bandpass(np.arange(10.0), FS, 0.1, 0.9)
    msg = assert_one_line_error(e)
    assert f"need ≥ {min_length(sos)}" in msg
    bandpass(np.arange(float(min_length(sos))), FS, 0.1, 0.9)  # the named minimum is enough
    with pytest.raises(AeromagError, match="low < high") as e:
        bandpass(np.arange(500.0), FS, 0.9, 0.1)
    assert_one_line_error(e)
    with pytest.raises(AeromagError, match="shape") as e:
        bandpass(np.zeros((50, 2, 2)), FS, 0.1, 0.9)
    assert_one_line_error(e)
    with pytest.raises(AeromagError, match="sample rate") as e:
        bandpass(np.arange(500.0), 0.0, 0.1, 0.9)
    assert_one_line_error(e)
    with pytest.raises(AeromagError, match="order") as e:
        bandpass(np.arange(500.0), FS, 0.1, 0.9, 0)
    assert_one_line_error(e)
    with pytest.raises(AeromagError, match="cutoff") as e:
        highpass(np.arange(500.0), FS, FS)
    assert_one_line_error(e)
    with pytest.raises(AeromagError, match="cutoff") as e:
        lowpass(np.arange(500.0), FS, 0.0)
    assert_one_line_error(e)
