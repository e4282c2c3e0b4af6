# Rules of the nscd step (see README).
