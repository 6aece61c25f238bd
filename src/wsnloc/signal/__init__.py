"""Signal processing: IMU resampling."""
