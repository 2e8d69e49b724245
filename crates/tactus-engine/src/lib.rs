#![forbid(unsafe_code)]

pub mod resample;
pub mod source;
