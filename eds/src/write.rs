//! Canonical EDS and DCF writers: [`crate::model::Model`] → text.
