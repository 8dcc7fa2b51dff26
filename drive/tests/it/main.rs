//! The integration tests of `drive`, one module per former test file, linked into one
//! binary: `cargo test -p drive --test it` runs them all, `... --test it -- MODULE::` one module.

mod drive_sim;
mod drives_akd;
mod drives_akd_e2e;
mod drives_common;
mod drives_conformance;
mod drives_drcs;
mod drives_drcs_e2e;
mod drives_drvi;
mod drives_drvi_e2e;
mod e2e_cli;
mod e2e_guarding;
mod hub_cli;
mod machine_cli;
mod machines;
mod manual_frames;
mod motion_common;
mod motion_homing;
mod motion_modes;
mod motion_profile;
mod motion_props;
mod motion_trace;
mod node_params;
mod node_props;
mod node_run;
mod node_sim;
mod node_storage;
mod support;
