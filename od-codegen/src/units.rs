//! Unit scaling from the device sidecar (in progress).

use eds::model::Model;
use proc_macro2::TokenStream;

use crate::diag::Sink;
use crate::plan::Plan;

pub(crate) fn module(
    _model: &Model,
    _plan: &Plan<'_>,
    _sc: &devices::sidecar::Sidecar,
    _sink: &mut Sink,
) -> TokenStream {
    TokenStream::new()
}
