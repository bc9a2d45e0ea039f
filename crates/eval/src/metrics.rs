//! Image error metrics. To be written (helper).
