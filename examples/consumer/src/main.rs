//! The report natively: `cargo run` in this directory.

fn main() {
    match fem2d_consumer::report() {
        Ok(text) => print!("{text}"),
        Err(e) => {
            eprintln!("error: {e}");
            std::process::exit(1);
        }
    }
}
