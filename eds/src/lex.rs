//! The nom lexer: decoded text → lossless [`crate::ast::Document`].
