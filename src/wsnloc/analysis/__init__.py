"""Studies computed in memory from the simulator and the library (no workflow files)."""
