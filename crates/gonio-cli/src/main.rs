//! `gonio`: the command-line front of the Gonio gonioreflectometer system (the
//! library `gonio_cli` holds all of it).

fn main() -> std::process::ExitCode {
    gonio_cli::main()
}
