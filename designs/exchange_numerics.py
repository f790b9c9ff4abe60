"""The numerical limits both exchanges share (the compiled one, `designs/kernels.py`, and the numpy row exchange,
`designs/row_exchange.py`), so the two judge singularity, gains and convergence alike."""

#: X'X whose condition number passes this is singular to working precision.
SINGULAR_CONDITION = 1e12
#: The ridge put on the diagonal of a singular X'X, relative to its mean diagonal (at least 1), so an exchange can still
#: move a singular start towards a design that estimates every term.
RIDGE = 1e-6
#: A rank-two update whose 2 x 2 core has a determinant this small, relative to its terms, has lost it in rounding:
#: (X'X)^-1 is made afresh instead.
CORE_LOST = 1e-8
#: A gain in log det(X'X) (relative, under I and A) below this is no gain.
GAIN_TOLERANCE = 1e-10
#: The most passes over the runs one exchange makes.
MAX_PASSES = 500
