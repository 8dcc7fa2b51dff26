//! Parsing and formatting of CiA 306 values (numbers, `$NODEID` expressions, strings, bytes).
