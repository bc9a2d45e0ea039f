//! Plots as PNG. To be written (helper).
