"""Deviation from the nominal pipe and ovality per station."""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy import interpolate

from ._centreline import Pipe, section_fits

__all__ = ["Ovality", "deviation", "ovality"]

#: Stations over which the sections' mean radius and ovality are running medians.
WINDOW = 9
#: Clocks round the pipe at which the section's uncertainty is taken before it is
#: interpolated: linear interpolation of a second harmonic at 360 / 64 degrees is within
#: 0.5 % of its amplitude.
ERROR_CLOCKS = 64


def deviation(pipe: Pipe, x) -> np.ndarray:
    """(N,) signed distance in metres of the positions `x` (N, 3) from the nominal pipe.

    Negative is inward (a dent or a deposit), positive outward (a bulge or wall loss).
    Positions beyond the centreline's ends are NaN.
    """
    return pipe.locate(x)[2] - pipe.radius


@dataclass(frozen=True, eq=False)
class Ovality:
    """Ovality per station along a pipe.

    Attributes
    ----------
    axial : (K,) float64
        Station centres, metres along the centreline.
    ovality : (K,) float64
        ``(D_max - D_min) / D_nominal`` of the section fitted at each station; NaN where
        the data do not go all round the pipe.
    d_max, d_mean, d_min : (K,) float64
        The fitted section's largest, mean and smallest diameter, metres.
    major_clock : (K,) float64
        Clock angle of the largest diameter, degrees in [0, 180).
    offset : (K, 2) float64
        The fitted section's centre off the centreline, metres, towards 12 and 3 o'clock
        (the centreline's own error, at a scale finer than its knots); NaN where no
        section is fitted.
    scatter : (K, 5) float64
        Each station's own fit (``a0, a1, b1, a2, b2``, see `ovality`) less the running
        medians the section is made of, metres: how far the section is from what the
        station alone shows (`section_error`); NaN where not fitted (the centre's
        columns), or where the data do not go all round (the others).
    """

    axial: np.ndarray
    ovality: np.ndarray
    d_max: np.ndarray
    d_mean: np.ndarray
    d_min: np.ndarray
    major_clock: np.ndarray
    offset: np.ndarray
    scatter: np.ndarray

    def __post_init__(self) -> None:
        for value in (self.axial, self.ovality, self.d_max, self.d_mean, self.d_min,
                      self.major_clock, self.offset, self.scatter):  # fmt: skip
            value.flags.writeable = False

    def section_at(self, axial, clock, otherwise: float) -> np.ndarray:
        """(N,) distance (m) from the centreline to the fitted section at `axial` (m) and
        `clock` (degrees): the mean radius ``(D_max + D_min) / 4``, plus ``(D_max - D_min)
        / 4 cos(2 (clock - major_clock))``, plus the section centre's `offset` seen at that
        clock, interpolated between the stations that measured one, and `otherwise` where
        none did. A defect is what leaves this section, so an error of the centreline is
        none."""
        half = 0.25 * (self.d_max - self.d_min)
        angle = np.radians(2.0 * self.major_clock)
        coef = np.stack([0.25 * (self.d_max + self.d_min), *self.offset.T,
                         half * np.cos(angle), half * np.sin(angle)], axis=1)  # fmt: skip
        return _harmonics(axial, clock, self.axial, coef, otherwise)

    def section_error(self, axial, clock) -> np.ndarray:
        """(N,) how uncertain the section is at `axial` (m) and `clock` (degrees), metres:
        the running median over `WINDOW` stations of the distance by which each station's
        own fit departs from the section at that clock (`scatter`), interpolated between
        the stations and over `ERROR_CLOCKS` clocks round the pipe.

        Where the centreline cannot quite follow the wall (the start of a tight bend, a
        section seen from afar), neighbouring stations disagree by a millimetre or so, and
        the running medians smooth that over: a residual there is as uncertain as that. A
        dent a few times the points' noise deep moves its own stations' fits, most at its
        clock; a median over the stations the section itself is a median over does not
        follow those few, as the section does not, so a dent does not raise its own cells'
        error and hide itself.
        """
        axial, clock = np.broadcast_arrays(
            np.asarray(axial, dtype=np.float64), np.mod(np.asarray(clock, dtype=np.float64), 360.0)
        )
        inside = np.clip(axial, self.axial[0], self.axial[-1])
        return self._error_table(np.stack([inside, clock], axis=-1)).reshape(axial.shape)

    @cached_property
    def _error_table(self) -> interpolate.RegularGridInterpolator:
        """`section_error`'s running medians at the stations and `ERROR_CLOCKS` clocks (the
        first again at 360 degrees), interpolated linearly."""
        clocks = np.arange(ERROR_CLOCKS + 1) * (360.0 / ERROR_CLOCKS)
        own = np.abs(
            _harmonics(self.axial[:, None], clocks[None, :], self.axial, self.scatter, 0.0)
        )
        typical = np.stack([_running_median(column) for column in own.T], axis=1)
        if self.axial.size == 1:  # one station: the same all along
            return interpolate.RegularGridInterpolator(
                (np.r_[self.axial, self.axial + 1.0], clocks), np.repeat(typical, 2, axis=0)
            )
        return interpolate.RegularGridInterpolator((self.axial, clocks), typical)


def ovality(pipe: Pipe, x, *, step: float | None = None, located=None) -> Ovality:
    """Ovality of the wall positions `x` (N, 3) in stations of `step` metres along `pipe`.

    Each station fits ``a0 + a1 cos t + b1 sin t + a2 cos 2t + b2 sin 2t`` to the distance
    from the centreline over the clock angle t, robustly (a dent does not pull it; see
    `station_fits`); a station whose data leave a sector of 22.5 degrees empty (an
    opening, a shadow) measures no radius or ovality, only its centre ``(a1, b1)``, by a
    circle (`section_fits`, as the centreline is). The
    mean radius, the centre and the second harmonic are then medians over `WINDOW`
    stations, so one station disturbed (a branch's seam, a defect) does not set them.
    With ``A2 = hypot(a2, b2)`` the diameters are ``2 (a0 +- A2)``, so the ovality is ``4
    A2 / D_nominal``. `step` defaults to a tenth of the radius.
    """
    if located is None:
        located = pipe.locate(np.asarray(x, dtype=np.float64))
    fits = section_fits(pipe, located, step=step)
    own = np.where(fits["complete"][:, None], fits["coef"], np.nan)
    own[:, 1:3] = np.where(fits["centred"][:, None], fits["circle"][:, 1:3], np.nan)
    medians = np.stack([_running_median(c) for c in own.T], axis=1)
    a0, a1, b1, a2, b2 = medians.T
    amplitude = np.hypot(a2, b2)
    return Ovality(
        axial=fits["axial"],
        ovality=2.0 * amplitude / pipe.radius,
        d_max=2.0 * (a0 + amplitude),
        d_mean=2.0 * a0,
        d_min=2.0 * (a0 - amplitude),
        major_clock=np.mod(0.5 * np.degrees(np.arctan2(b2, a2)), 180.0),
        offset=np.stack([a1, b1], axis=1),
        scatter=own - medians,
    )


def _harmonics(axial, clock, stations, coef, first: float) -> np.ndarray:
    """``c0 + c1 cos t + c2 sin t + c3 cos 2t + c4 sin 2t`` at `axial` (m) and clock t
    (`clock`, degrees; the two broadcast), each coefficient of `coef` (K, 5) given at the
    `stations` (K,) (m) and interpolated between its finite values: `first` for c0 where
    it has none, 0 for the others."""
    axial = np.asarray(axial, dtype=np.float64)
    once = np.radians(np.asarray(clock, dtype=np.float64))
    terms = (1.0, np.cos(once), np.sin(once), np.cos(2 * once), np.sin(2 * once))
    total = np.zeros(np.broadcast_shapes(axial.shape, once.shape))
    for column, term, default in zip(coef.T, terms, (first, 0.0, 0.0, 0.0, 0.0), strict=True):
        known = np.isfinite(column)
        if known.any():
            total += np.interp(axial, stations[known], column[known]) * term
        else:
            total += default * term
    return total


def _running_median(values: np.ndarray) -> np.ndarray:
    """(K,) median of the finite `values` over `WINDOW` stations centred on each; NaN stays."""
    half = WINDOW // 2
    padded = np.pad(values, half, constant_values=np.nan)
    windows = np.lib.stride_tricks.sliding_window_view(padded, WINDOW)
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        median = np.nanmedian(windows, axis=1)
    return np.where(np.isfinite(values), median, np.nan)
