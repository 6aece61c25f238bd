"""Estimators: every position estimator of the project behind one interface.

`registry.run(name, RunData, parameters)` -> estimates (t, x, y, covariance where there is
one). See registry for the list, parameters for their checking, and the part modules
(fixes, trackers, bayes, motion, measurements, inertial) for the equations.
"""
