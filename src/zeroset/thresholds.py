"""The thresholds of phase 1's rules, in one place, each with its rule and its reason.

Every number a rule of docs/rules.md compares against or counts with lives here, named once;
the modules that apply the rules import it. Each comment gives the rule (Rn, as in the
ledger), then either the derivation (**derived**) or what the value was chosen on
(**chosen**). Lengths are in rho+delta (the cloud's neighbourhood radius, ``rho_delta``)
or in a point's own radius where the comment says so; angles in degrees unless named
otherwise. Settings a user may change are `ReconstructionConfig` fields, not these.

What is left in the modules is not a threshold: table encodings (`_mc_table`), chunk sizes,
numerical guards (`_kernels.jets.RIDGE`) and the tiles' plan (`tiles`). The registration
of several scans (R2) keeps small_gicp's solver settings in `registration`.
"""

from __future__ import annotations

import numpy as np

# -- Parameters (R3, R5) ---------------------------------------------------------------

#: R3, R5: points whose neighbourhoods measure the spacing and the noise, and neighbours
#: searched around each for the spacing. **Chosen** (not recorded).
WIDE_ROWS = 2_000
SPACING_K = 64
#: R3, R8, R30: directions around a point in its tangent plane, and how many must hold a
#: neighbour for the point to be surrounded. **Chosen** (not recorded); a point at a
#: straight edge fills 4 of 8, so 6 leaves it out.
SECTORS = 8
SECTORS_NEEDED = 6
#: R5: neighbours of a sample point in the quadric noise estimate. **Chosen** on the
#: bunny scan and the 2 mm-noise pipes (docs/rules.md, R5).
NOISE_K = 128

# -- Cell means (R7) -------------------------------------------------------------------

#: R7: shortest mean of a cell's unit directions to its sensors for the cell to have one.
#: **Chosen** (not recorded) between two bounds: unit directions within 60° of one
#: another average to at least 0.5, opposite ones to 0.
SPLIT_VIEW = 0.25

# -- Radii (R8, R9) --------------------------------------------------------------------

#: R8: largest per-point radius, over rho+delta; a point that would need more is an
#: outlier or lies at an edge, and keeps rho+delta. **Chosen** (not recorded).
RADIUS_CAP = 2.0
#: R6, R8, R9: nearest neighbours (the point included) whose median spacing is a point's;
#: with `k_max`, the fewest cells a cloud must fill. **Chosen** (not recorded); the
#: default `k_max`.
SMOOTH_K = 16
#: R9: range bins of equal count whose median plane residuals fit the range-noise model.
#: **Chosen** (not recorded).
RANGE_BINS = 10
#: R8, R30: nearest neighbours found per point: enough to reach across the gap between
#: scan lines (the sectors of R8, the chords of R30). **Chosen** (not recorded).
WIDE_K = 32

# -- Orientation (R13-R18) -------------------------------------------------------------

#: R13, R15: a component is joined to another only by a pair of points whose step lies
#: within this many degrees of both their tangent planes; two components face each other
#: across a gap where the step leaves both planes by more. **Chosen** on the 3DTK SICK
#: scan000; kept since the joins were made (the gap bridges allow `ALONG`).
ON_ONE_SURFACE = 30.0
#: R15: components whose points come within this many of their longest edge of each other
#: are neighbours that must not point the same way across the gap; the largest this many
#: components take part, with at most this many points each. **Chosen** on two plates,
#: two coaxial pipes and a rack of eight pipes.
STACK_REACH, STACK_COMPONENTS, STACK_SAMPLES = 6.0, 16, 20_000
#: R16: |cosine| between a normal and the direction to its sensor from which the sensor
#: decides the normal's sign: cos 60°, the beam meets the surface within 60° of its
#: normal. **Chosen** (not recorded): nearer grazing, and in sparse rings far down a pipe,
#: a poorly fitted plane may face the sensor by chance; such points follow the tree.
FACING = 0.5
#: R17: mean |cosine| from which a component's own sensors decide its sign in the vote.
#: **Chosen** (not recorded): cos 73°.
DECISIVE = 0.3
#: R18: share of disagreement between sensors and tree above which the sensors are not
#: trusted point by point. **Chosen**: right sensor positions leave well under 1 % (0.06 %
#: on the Stanford bunny's ten scans), one sensor on the wrong side of its scan about 3 %,
#: scan frames whose origins are no sensor positions 23 % (two scans of a torus).
UNTRUSTED = 0.05
#: R18: share of abrupt disagreement from which the tree, not the sensors, is taken to be
#: wrong. **Chosen**: 0.56 on a thin plate whose two sides one tree joined, 0 with every
#: sensor in a torus's hole.
ABRUPT = 0.1

# -- Local fits (R19-R26) --------------------------------------------------------------

#: R21: variance of a jet's value at its centre times (points in the support) / sigma^2,
#: for the kernel (1 - (d/h)^2)^2 over a uniformly sampled disc. **Derived** (Monte Carlo,
#: 2,000 trials).
JET_VARIANCE = 6.0
#: R21: bias of a jet's value at its centre per unit quartic coefficient times h^4, same
#: kernel. **Derived**: a quadric fitted to u^4 over the disc passes 0.025 h^4 below it.
JET_BIAS = 0.025
#: R21, R24: supports, in rho+delta: the smallest, and the largest. **Chosen** (not
#: recorded); the largest keeps every value within `REACH`, the tiles' halo.
MIN_SUPPORT, MAX_SUPPORT = 1.0, 6.0
#: R21: support of the pilot fits, in rho+delta. **Chosen** on the 2 mm-noise pipe at
#: 20k, 200k and 1M points (docs/rules.md, R21).
PILOT_SUPPORT = 2.5
#: R22: second support of the pilot fits, as a share of theirs, and the margin over the
#: noise variance from which the difference counts as detail. **Chosen**: on smooth
#: synthetic surfaces the measure stays below 2 in 99.9 % of the pilots; on the real
#: scans its median is 10.
DETAIL_SUPPORT, DETAIL_MARGIN = 0.6, 3.0
#: R20: cells a fit's support should hold, and the neighbours searched for them.
#: **Chosen** on the 1M-point pipe (docs/rules.md, R20).
CELLS_PER_SUPPORT, FIT_K = 40, 64
#: R20, R25: fewest cells a jet is fitted to, whatever its support. **Chosen** (not
#: recorded); the default `k_max`.
MIN_CELLS = 16
#: R24: a jet whose mean squared residual exceeds this many times the noise variance is
#: refitted on half its support, at most this many times. **Chosen** (not recorded): a
#: residual twice the noise, as at a crease or a second sheet in the support.
MISFIT_LIMIT, MISFIT_HALVINGS = 4.0, 2
#: R19: jets blended at a position (the partition of unity uses one more for its reach).
#: **Chosen** (not recorded).
BLEND_K = 8
#: R25: a neighbour further from a jet's tangent plane than the surface's curvature
#: explains, by this many rho+delta or this many noise levels if more, is on another sheet.
#: **Chosen** on two plates 4 cm apart (3.1 rho+delta, 1 mm noise) and two coaxial pipes;
#: four noise levels leave one point in 16,000 of a Gaussian sheet out.
SHEET, SHEET_NOISE = 1.0, 4.0
#: R26: oriented planes that vote on each jet's orientation. **Chosen** on a simulated
#: scan where one plane turned the wrong way made a 30-face component.
ORIENT_K = 8
#: R19-R24: every value of the surface lies within this many rho+delta of all the points
#: it depends on. **Derived**: blend (half a support), support, the pilots that set it and
#: the feet. **Chosen** above their sum (not recorded).
REACH = 16.0

# -- Signed distance (R28-R32) ---------------------------------------------------------

#: R28: nearest tangent planes tried, in order, until one's foot point lies near the data;
#: a single badly fitted plane then cannot open a hole. **Chosen** (not recorded).
CANDIDATES = 3
#: R29: values closer to zero than this fraction of the cube size are pushed off zero, so
#: no contour vertex lands on a grid vertex (an exact zero makes degenerate triangles).
#: **Chosen** (not recorded).
ZERO_NUDGE = 1e-3
#: R30, R43: longest chord across a gap, its points' reach in the undefined test, and
#: their spacing along it, over rho+delta. **Chosen** on the 0.1 m simulated scan pipe,
#: whose bands are 3-3.5 cm apart at rho+delta = 1.4 cm; points half a radius apart with a
#: reach of 1.25 leave no gap between consecutive points' balls.
BRIDGE_LENGTH = 3.5
BRIDGE_REACH = 1.25
BRIDGE_STEP = 0.5
#: R30: neighbours searched around a point whose nearest ones leave directions empty.
#: **Chosen** (not recorded).
EDGE_K = 256
#: R30: gap-bridge points, as a share of the fitted points, from which a run warns of
#: them. **Chosen**: an evenly sampled sphere, pipe or torus makes 0.8-1 %, a scan with
#: gaps between its lines tens of percent.
BRIDGES_NOTED = 0.02
#: R31: least cosine between a chord and the side of its first point away from its
#: neighbours, within about 30° (cos 30° = 0.87): chords across a gap leave that way;
#: chords along an open end, or across a round hole off its centre, do not. **Chosen**
#: (not recorded).
CROSSING = 0.85
#: R32: a chord lies within this many degrees of the tangent planes at both its ends.
#: **Chosen** on the SICK scans: within 30° (`ON_ONE_SURFACE`) their noisy normals lose
#: bridges they need (mean distance 50.9 -> 64.1 mm on scan 0).
ALONG = 60.0

# -- Contour and repair (R34, R38, R43) ------------------------------------------------

#: R34: a sign change whose two values differ by more than this many cube sizes is no
#: zero crossing of a distance function but a jump of the nearest tangent plane.
#: **Derived** in part: |grad f| = 1, so along one cube edge a distance changes by at most
#: one cube size; the factor 2 is chosen (not recorded).
MAX_JUMP = 2.0
#: R38, R43: widest hole closed, over rho+delta. **Derived**: the signed distance is
#: defined within rho+delta of the data on either side, so the data cannot resolve a
#: narrower one.
HOLE_WIDTH = 2.0
#: R43: most edges of a loop that the rim cut may close. **Chosen** (not recorded).
WIDTH_EDGES = 128
#: R43: fractions of the way from a loop's centroid to each of its vertices and edge
#: midpoints at which the fan over it is sampled. **Chosen** (not recorded).
FAN_FRACTIONS = (0.0, 0.25, 0.5, 0.75)

# -- Rim (R40-R43) ---------------------------------------------------------------------

#: R40: tangential offset of the centroid of a half disc of radius 1 from its centre.
#: **Derived**: 4 / (3 pi).
EDGE_OFFSET = 4.0 / (3.0 * np.pi)
#: R40: radius of the disc whose centroid is taken, over the radius of the nearest point.
#: **Chosen** (not recorded).
DISC = 1.5
#: R40: smallest variance across the data in a disc, over its radius squared; less is a
#: curve of points, not a surface. **Chosen** below two derived values: 1/4 for a full
#: disc, 0.07 for a half disc.
THIN = 0.02
#: R40: fewest points in a disc for its centroid to count; with fewer the vertex is
#: outside. **Derived**: three points span a plane.
DISC_POINTS = 3
#: R40: vertices within this many largest radii (plus one cube) of a boundary vertex are
#: tested, and vertices farther than this many radii from the nearest point (a hole in
#: the data that the lattice closed). **Chosen** above a derived bound: the lattice
#: defines the surface at most a radius and a cube past the data.
BAND = 2.5
FAR = 0.5
#: R41: steps of regula falsi (Illinois) that place each crossing on its edge, and how
#: close to an end of its edge, over the edge's length, a cut moves that end (no
#: slivers, as in isosurface stuffing). **Chosen** (not recorded).
CROSSING_STEPS = 4
SNAP = 0.2
#: R42: radius of the empty balls that open a hole to its measured points, over the
#: radius of the point each reaches to. **Derived**: half the longest gap bridge, so no gap
#: the bridges may cross is opened, and no hole wider than a bridge may cross is closed.
HOLE_BALL = BRIDGE_LENGTH / 2.0
#: R42: how far, over the smallest empty ball's radius, a centre may climb the distance to
#: the points, and in how many steps. **Chosen** (not recorded).
CLIMB = 0.5
CLIMB_STEPS = 8
#: R42: points within this many radii of an empty ball count around it, and the widest
#: angle (radians) between two of them about its centre for the ball to be a hole.
#: **Chosen** (not recorded).
ENCLOSE = 1.25
OPEN_ANGLE = np.pi / 2

# -- Refinement (R44, R45) -------------------------------------------------------------

#: R44: Newton steps per projection. **Chosen** (not recorded).
PROJECTION_STEPS = 2
#: R45: most four-way splits of every triangle, and the chord sag allowed: this fraction
#: of the radius 1 / kappa, or this fraction of the noise of one point, whichever is
#: larger. **Chosen** on the 20k pipe and the Method of Cubes benchmark's six clouds.
MAX_LEVELS = 3
CHORD_RELATIVE, CHORD_NOISE = 1e-4, 0.1

# -- Simplification (R46, R47) ---------------------------------------------------------

#: R46: the default tolerance, in standard errors of the fitted surface's height
#: (`Jets.uncertainty`). **Derived**: a mesh within two standard errors of the fit is
#: within the fit's own 95 % band of the truth wherever the fit is.
UNCERTAINTIES = 2.0
#: R46: no collapse may fold two neighbouring faces further apart than this (degrees),
#: unless they were folded as much before, nor leave a sample on a face turned further
#: than this from the sample's own normal. **Chosen** (not recorded); with the fold test
#: alone a face at the 30k pipe's rim turned 64 degrees from the wall.
MAX_FOLD_DEGREES_SIMPLIFY = 30.0
#: R46, R47: the samples, and the points each triangle is checked at, are held this share
#: of the tolerance from the other mesh, since the meshes part a little further between
#: them. **Chosen** on the 60k cylinder (a median stray 5 % over the tolerance at 1.0) and
#: random height fields (7 % past the tolerance between the points at 1.0).
SAMPLE_MARGIN = 0.8
#: R47: most rounds of the check of every triangle against the dense mesh, each splitting
#: the longest edge of every triangle that strays; the rounds stop when none strays.
#: **Chosen** on 60 random height fields of the property test (seeded): up to 8 rounds
#: were needed, and 4 left a triangle up to 1 % past the tolerance in 3 of them; twice the
#: most seen. A round re-measures only what its splits changed.
CHECK_ROUNDS = 16
