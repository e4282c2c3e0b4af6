# Rules of the harmonic step (see README).
