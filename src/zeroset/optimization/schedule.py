"""Defaults of the mesh optimisation, relative to the data so that they need no tuning.

Hoppe et al. (1993) give c_rep and kappa in a frame where the data fill the unit cube and
tune them per model. Here both follow from the data:

- ``kappa``: the springs (Hoppe 1993, §4.1) are a regulariser whose weight must be measured
  against the data term, which grows with the points per vertex. The schedule starts at
  ``KAPPA_START`` times the points per starting vertex, N / M0, and falls by the factors
  in ``KAPPA_STEPS`` (Hoppe's 1e-2, 1e-3, 1e-4, 1e-8), ending with almost no springs.
- ``c_rep``: a vertex is kept when it lowers E_dist by more than c_rep. A vertex adds about
  one parameter that E_dist can see (its offset along the normal), and fitting noise with
  one more parameter lowers E_dist by sigma^2 on average, so a c_rep near sigma^2 crumples
  the mesh into folds. Schwarz's criterion prices a parameter at sigma^2 ln N (Schwarz
  1978, the Bayesian information criterion), so ``c_rep = C_REP_FACTOR sigma^2 ln N``:
  independent of the starting mesh, and growing slowly with the points, so that more
  points buy a finer mesh only where the shape needs it. sigma is the robust spread of the
  distances from the points to the starting mesh (1.4826 times their median).
"""

KAPPA_START = 1e-2
KAPPA_STEPS = (1.0, 1e-1, 1e-2, 1e-6)
C_REP_FACTOR = 1.0
#: Points farther than this many sigma from the starting mesh are left out (outliers).
MAX_DISTANCE_SIGMAS = 5.0
#: A move may not fold two neighbouring faces further apart than this (degrees), unless
#: they were folded as much before.
MAX_FOLD_DEGREES = 60.0
#: Passes per kappa; a level ends earlier when a pass accepts nothing or the fit after it
#: moves no vertex by more than MOVED_SIGMAS x sigma. A fit ends, too, at the first solve
#: that moves no vertex by more: the passes would take it as no change.
MAX_PASSES = 4
MOVED_SIGMAS = 0.1
