# Rules of the sample step (see README).
