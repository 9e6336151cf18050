//! ARCHITECTURE.md's crate table says which zwarp crates each crate depends on; this test keeps
//! it equal to the Cargo.toml files, so the map stays true when the layout changes.

use std::collections::BTreeSet;
use std::path::Path;

const SHORT: [&str; 11] =
    ["core", "scene", "raster", "metrics", "warp", "color", "cull", "shadows", "gpu", "viz", "vr"];

/// zwarp crates in a Cargo.toml's `[dependencies]` (short names: `zwarp-warp` -> `warp`).
fn cargo_deps(manifest: &Path) -> BTreeSet<String> {
    let text = std::fs::read_to_string(manifest).unwrap();
    let mut in_deps = false;
    let mut out = BTreeSet::new();
    for line in text.lines() {
        let l = line.trim();
        if l.starts_with('[') {
            in_deps = l == "[dependencies]";
            continue;
        }
        if !in_deps {
            continue;
        }
        let key = l.split(['=', '.', ' ']).next().unwrap_or("");
        if let Some(short) = key.strip_prefix("zwarp-") {
            out.insert(short.to_string());
        }
    }
    out
}

/// `crate -> zwarp crates it depends on` from the table (`| `zwarp-x` | owns | depends on |`).
fn table() -> Vec<(String, Option<BTreeSet<String>>)> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let text = std::fs::read_to_string(root.join("ARCHITECTURE.md")).unwrap();
    let mut rows = Vec::new();
    for line in text.lines().filter(|l| l.starts_with("| `zwarp") || l.starts_with("| `tools/`")) {
        let cells: Vec<&str> = line.trim_matches('|').split(" | ").map(str::trim).collect();
        // `tools/` rows carry a remark after the folder name.
        let name = cells[0].split_whitespace().next().unwrap_or("").trim_matches('`').to_string();
        let deps = cells.last().unwrap();
        if *deps == "everything" || deps.starts_with("everything") {
            rows.push((name, None));
            continue;
        }
        // Drop parenthetical remarks, then keep the names of zwarp crates.
        let mut plain = String::new();
        let mut depth = 0;
        for c in deps.chars() {
            match c {
                '(' => depth += 1,
                ')' => depth -= 1,
                _ if depth == 0 => plain.push(c),
                _ => {}
            }
        }
        let set = plain.split(',').map(str::trim).filter(|d| SHORT.contains(d)).map(String::from).collect();
        rows.push((name, Some(set)));
    }
    rows
}

#[test]
fn the_crate_table_matches_the_manifests() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let rows = table();
    let mut crates: Vec<String> = std::fs::read_dir(root.join("crates"))
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.path().join("Cargo.toml").is_file())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    crates.sort();
    let mut wrong = Vec::new();
    for c in &crates {
        let Some((_, listed)) = rows.iter().find(|(n, _)| n == c) else {
            wrong.push(format!("ARCHITECTURE.md has no row for {c}"));
            continue;
        };
        let actual = cargo_deps(&root.join("crates").join(c).join("Cargo.toml"));
        // "everything": the binary depends on every library crate but the facade.
        let expected = listed.clone().unwrap_or_else(|| SHORT.iter().map(|s| s.to_string()).collect());
        if expected != actual {
            wrong.push(format!("{c}: ARCHITECTURE.md says {expected:?}, Cargo.toml has {actual:?}"));
        }
    }
    // The tools crate at the root.
    match rows.iter().find(|(n, _)| n == "tools/") {
        Some((_, Some(listed))) => {
            let actual = cargo_deps(&root.join("tools/Cargo.toml"));
            if *listed != actual {
                wrong.push(format!("tools/: ARCHITECTURE.md says {listed:?}, Cargo.toml has {actual:?}"));
            }
        }
        _ => wrong.push("ARCHITECTURE.md has no dependency row for tools/".into()),
    }
    for (n, _) in &rows {
        if !crates.contains(n) && n != "tools/" {
            wrong.push(format!("ARCHITECTURE.md has a row for {n}, which is not a crate"));
        }
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}
