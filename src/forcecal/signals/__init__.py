"""Recorded signals (METHOD.md section 3, step 1, and section 6): the fundamental, the
harmonics of steady records and their noise, mains hum, the checks a record must pass, and the
filters and smoothers of the any-drive path (Kalman, Wiener, the record's ends)."""
