"""Physically modelled campaign simulator: writes raw logs exactly as a testbed logger would."""
