//! The HTML report. To be written (helper).
