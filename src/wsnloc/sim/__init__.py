"""Physically modelled campaign simulators: write raw logs exactly as a testbed logger would."""

from wsnloc.sim import cricket, newcom

SIMULATORS = {"newcom": newcom.simulate_run, "cricket": cricket.simulate_run}
