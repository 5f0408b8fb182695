"""Scanner emulators for the SIL (see :mod:`.base`): ``tim5xx``, ``lms1xx``, ``lms5xx`` (:mod:`.sick`), ``ust`` and
``urg`` (:mod:`.scip`), ``rplidar`` (:mod:`.rplidar`)."""
