"""Pure stage functions over arrays (histograms, mean shift, level sets, Kalman, association)."""
