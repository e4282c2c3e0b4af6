# Rules of the simulation step (see README).
