//! The command line: one file per command, each turning its arguments into a library call and a
//! typed report. Option groups several commands share are defined once here and flattened.

pub mod choice;
