# Rules of the rheology step (see README).
