//! `cargo xtask <command>`: project automation, one module per command.

use std::process::ExitCode;

const USAGE: &str = "usage: cargo xtask <command>

commands:
  gen [--check]   regenerate generated/ from the device files and network descriptions,
                  printing what changed in each changed device file (--check: fail if stale)
  size [--elf F]  build the example firmware for each device (thumbv7em-none-eabihf), print
                  its sections, fail above the size budget or when core::fmt is linked
  deps            read every crate's module imports and fail on any import circle";

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some((cmd, rest)) = args.split_first() else {
        eprintln!("{USAGE}");
        return ExitCode::FAILURE;
    };
    let result = match cmd.as_str() {
        "gen" => xtask::codegen::main(rest),
        "size" => xtask::size::main(rest),
        "deps" => xtask::deps::main(rest),
        "help" | "--help" | "-h" => {
            println!("{USAGE}");
            Ok(())
        }
        other => Err(format!("unknown command `{other}`\n\n{USAGE}")),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
