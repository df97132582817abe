//! The generated tables of the docs agree with the declarations they come from: the key table of
//! `docs/configuration.md` with the configuration sections (`FilterConfig::key_docs`), and the
//! method table of `docs/methods.md` with the method registry (`Method::ALL`). When a
//! declaration changes, regenerate the tables with
//!
//! ```text
//! UPDATE_DOCS=1 cargo test --test integration docs_tables::
//! ```

use std::path::Path;

use uwbimu_rs::app::methods::{Input, Method};
use uwbimu_rs::vocabulary::config::{ConfigValue, FilterConfig};

/// A default as the docs show it.
fn show(value: Option<&ConfigValue>) -> String {
    match value {
        None => "unset".into(),
        Some(ConfigValue::Scalar(x)) => format!("{x}"),
        Some(ConfigValue::Flag(b)) => format!("{b}"),
        Some(ConfigValue::Vector(v)) => format!("[{}]", v.iter().map(|x| format!("{x}")).collect::<Vec<_>>().join(", ")),
    }
}

fn config_table() -> String {
    let mut out = String::from("| key | default | meaning, unit, rule |\n|---|---|---|\n");
    for k in FilterConfig::key_docs() {
        out += &format!("| `{}` | {} | {} |\n", k.key, show(k.default.as_ref()), k.doc.replace('|', "\\|"));
    }
    out
}

fn method_table() -> String {
    let mut out = String::from("| method | takes | smoothing | streaming class | what |\n|---|---|---|---|---|\n");
    for m in Method::ALL {
        let info = m.info();
        let takes: Vec<&str> = m.inputs().map(Input::name).collect();
        let smoothing = info.smoothing.name();
        let class = info.streaming_class().map_or("–".to_string(), |c| format!("`{c}`"));
        let doc = info.doc.split_whitespace().collect::<Vec<_>>().join(" ");
        out += &format!("| `{}` | {} | {smoothing} | {class} | {} |\n", info.name, takes.join(", "), doc.replace('|', "\\|"));
    }
    out
}

/// Checks (or with `UPDATE_DOCS=1` rewrites) the block between `<!-- generated: NAME -->` and
/// `<!-- end generated -->` in `file`.
fn check_block(file: &str, name: &str, table: &str) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(file);
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{file}: {e}"));
    let open = format!("<!-- generated: {name} -->\n");
    let close = "<!-- end generated -->";
    let start = text.find(&open).unwrap_or_else(|| panic!("{file}: no `{}`", open.trim())) + open.len();
    let end = start + text[start..].find(close).unwrap_or_else(|| panic!("{file}: no `{close}` after `{name}`"));
    if std::env::var_os("UPDATE_DOCS").is_some() {
        std::fs::write(&path, format!("{}{table}{}", &text[..start], &text[end..])).expect("write docs");
    } else {
        assert_eq!(
            &text[start..end],
            table,
            "{file}: the `{name}` table is stale; regenerate it with `UPDATE_DOCS=1 cargo test --test integration docs_tables::`"
        );
    }
}

#[test]
fn configuration_key_table_is_the_declaration() {
    check_block("docs/configuration.md", "config keys", &config_table());
}

#[test]
fn method_table_is_the_registry() {
    check_block("docs/methods.md", "methods", &method_table());
}
