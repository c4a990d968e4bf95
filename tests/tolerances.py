"""Named tolerances of the test suite, one place (STYLE.md 4.6)."""

FD_STEP = 1e-6  # finite-difference step on the manifold
FD_ATOL = 2 * FD_STEP**0.5  # central-difference error bound used for Jacobians
SYMBOLIC_ATOL = 1e-9  # same algorithm twice in float64 (CasADi vs Pinocchio)
STANDING_ATOL = 1e-3  # [m] soles on the ground in a standing posture
CONTACT_POS_ATOL = 1e-3  # [m] stance sole position error in a plan
CONTACT_ROT_ATOL = 1e-3  # [rad] stance sole orientation error in a plan
EXPORT_ATOL = 1e-12  # exported numbers read back (the same float64 values; repr and CDR are exact)
