//! `docs/solvers.md` stays true: its capability table is [`capability_table`] (regenerate it
//! with `FEM2D_BLESS=1 cargo test -p fem-solvers --test suite capability_table`), and with the
//! `serde` feature its "Parameters" section names every scene key of every solver.

use fem_solvers::capability_table;
use std::path::PathBuf;

const BEGIN: &str = "<!-- capabilities:begin -->\n";
const END: &str = "<!-- capabilities:end -->";

fn doc_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../docs/solvers.md")
}

#[test]
fn docs_solvers_md_holds_the_current_table() {
    let path = doc_path();
    let text = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    let start = text.find(BEGIN).expect("the capabilities:begin marker") + BEGIN.len();
    let end = start
        + text[start..]
            .find(END)
            .expect("the capabilities:end marker");
    let table = capability_table();
    if text[start..end] == table {
        return;
    }
    if std::env::var_os("FEM2D_BLESS").is_some_and(|v| v == "1") {
        // Through a temporary file and a rename, so no reader sees a half-written page.
        let updated = format!("{}{table}{}", &text[..start], &text[end..]);
        let tmp = path.with_extension("md.tmp");
        std::fs::write(&tmp, updated).unwrap();
        std::fs::rename(&tmp, &path).unwrap();
        eprintln!("rewrote the capability table of {}", path.display());
    } else {
        panic!(
            "the capability table of docs/solvers.md is out of date; regenerate it with\n  FEM2D_BLESS=1 cargo test -p fem-solvers --test suite capability_table\nexpected:\n{table}"
        );
    }
}

/// Every key a solver reads appears, in backticks, in its subsection (`### \`name\``) of
/// "Parameters".
#[cfg(feature = "serde")]
#[test]
fn docs_solvers_md_lists_every_scene_key() {
    use fem_solvers::SolverKind;
    let text = std::fs::read_to_string(doc_path()).unwrap();
    for kind in SolverKind::ALL {
        let heading = format!("### `{kind}`");
        let start = text
            .find(&heading)
            .unwrap_or_else(|| panic!("docs/solvers.md has no section {heading}"));
        let section = &text[start + heading.len()..];
        let section = &section[..section.find("\n#").unwrap_or(section.len())];
        let keys = serde_json::to_value(kind.default_params()).unwrap();
        for key in keys.as_object().unwrap().keys() {
            assert!(
                section.contains(&format!("`{key}`")),
                "docs/solvers.md, {heading}: key `{key}` is not documented"
            );
        }
    }
}
