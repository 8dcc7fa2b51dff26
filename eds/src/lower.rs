//! Lowering and validation: [`crate::ast::Document`] → [`crate::model::Model`] + diagnostics.
