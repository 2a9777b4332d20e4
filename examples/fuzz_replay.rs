//! Runs fuzz inputs through a target's body and prints what each came to
//! (for the `pack` target, first the TOML scene the input builds):
//!
//! `cargo run --example fuzz_replay -- TARGET FILE...`
//!
//! TARGET is toml, nff, obj or pack (docs/reliability.md).

use whitted::fuzzing;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some((target, files)) = args.split_first() else {
        eprintln!("usage: fuzz_replay TARGET FILE...");
        std::process::exit(2);
    };
    let f = match target.as_str() {
        "toml" => fuzzing::toml,
        "nff" => fuzzing::nff,
        "obj" => fuzzing::obj,
        "pack" => fuzzing::pack,
        t => {
            eprintln!("unknown target {t}: toml, nff, obj or pack");
            std::process::exit(2);
        }
    };
    for file in files {
        let data = std::fs::read(file).unwrap_or_else(|e| {
            eprintln!("{file}: {e}");
            std::process::exit(2);
        });
        if target == "pack" {
            match fuzzing::pack_toml(&data) {
                Some(t) => println!("{file}: the scene\n{t}"),
                None => println!("{file}: too short for a scene"),
            }
        }
        let t0 = std::time::Instant::now();
        let o = f(&data);
        println!("{file}: {o:?} ({:.3} s)", t0.elapsed().as_secs_f64());
    }
}
