# Rules of the diagnosis step (see README).
