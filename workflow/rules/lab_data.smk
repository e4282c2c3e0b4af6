# Rules of the lab_data step (see README).
