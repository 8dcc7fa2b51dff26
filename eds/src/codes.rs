//! Every diagnostic code, with its lenient severity, whether it is a CiA 306 deviation, and a
//! one-line explanation.
