//! `docs/ARCHITECTURE.md` is the law. Between the workspace's crates Cargo enforces it (a crate
//! can name only its dependencies); this checks that the doc's package table says what the
//! manifests do. Inside the corrector, its room table: every `crate::…` path in `src/` must
//! point to a room the using room may use, and the table itself must only lean one way (up),
//! apart from the cycles it marks, which must still exist.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

const ROOT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");

/// One row of the table: the room and what it may use (`true`: marked `(cycle)`).
struct Row {
    room: String,
    may_use: Vec<(String, bool)>,
}

/// The room table of `docs/ARCHITECTURE.md`, in order (top of the table = bottom layer).
fn table(doc: &str) -> Vec<Row> {
    let mut rows = Vec::new();
    for line in doc.lines() {
        let cells: Vec<&str> = line.trim().trim_matches('|').split('|').collect();
        if cells.len() != 3 || !line.starts_with("| `") {
            continue;
        }
        let room = cells[0].trim().trim_matches('`').to_string();
        let may_use = cells[2]
            .split(',')
            .map(str::trim)
            .filter(|c| !c.is_empty() && *c != "—")
            .map(|c| {
                let cycle = c.contains("(cycle)");
                let name = c.replace("(cycle)", "").replace('`', "");
                (name.trim().to_string(), cycle)
            })
            .collect();
        rows.push(Row { room, may_use });
    }
    rows
}

/// The library crates' sources: the corrector, the room crates and the output session.
const LIBRARY_DIRS: [&str; 5] = [
    "src",
    "crates/nsrm-io/src",
    "crates/nsrm-chart/src",
    "crates/nsrm-export/src",
    "crates/nsrm-output/src",
];

/// The package table of `docs/ARCHITECTURE.md`: each package's directory and the workspace
/// packages its "depends on" cell names (the backticked `nsrm…` names).
fn package_table(doc: &str) -> BTreeMap<String, (String, BTreeSet<String>)> {
    let mut out = BTreeMap::new();
    for line in doc.lines() {
        let cells: Vec<&str> = line.trim().trim_matches('|').split('|').collect();
        if cells.len() != 4 || !line.starts_with("| `nsrm") {
            continue;
        }
        let name = cells[0].trim().trim_matches('`').to_string();
        let dir = cells[1].split('`').nth(1).unwrap_or("").to_string();
        let deps = cells[3]
            .split('`')
            .skip(1)
            .step_by(2)
            .filter(|w| *w == "nsrm" || w.starts_with("nsrm-"))
            .map(str::to_string)
            .collect();
        out.insert(name, (dir, deps));
    }
    out
}

/// The workspace packages a manifest's `[dependencies]` name (`name = { path = … }`).
fn path_dependencies(manifest: &str) -> BTreeSet<String> {
    let mut deps = BTreeSet::new();
    let mut in_deps = false;
    for line in manifest.lines() {
        let t = line.trim();
        if t.starts_with('[') {
            in_deps = t == "[dependencies]";
            continue;
        }
        if in_deps && t.contains("path = ") {
            if let Some((name, _)) = t.split_once('=') {
                deps.insert(name.trim().to_string());
            }
        }
    }
    deps
}

#[test]
fn packages_depend_as_the_architecture_doc_says() {
    let doc = std::fs::read_to_string(Path::new(ROOT).join("docs/ARCHITECTURE.md")).unwrap();
    let table = package_table(&doc);
    let root = std::fs::read_to_string(Path::new(ROOT).join("Cargo.toml")).unwrap();
    let members: Vec<String> = root
        .split("members = [")
        .nth(1)
        .and_then(|m| m.split(']').next())
        .unwrap()
        .split('"')
        .skip(1)
        .step_by(2)
        .map(str::to_string)
        .collect();
    assert!(members.len() >= 7, "workspace members: {members:?}");
    let mut problems = Vec::new();
    for m in &members {
        let manifest = std::fs::read_to_string(Path::new(ROOT).join(m).join("Cargo.toml")).unwrap();
        let name = manifest
            .lines()
            .find_map(|l| l.strip_prefix("name = \""))
            .and_then(|l| l.strip_suffix('"'))
            .unwrap()
            .to_string();
        let Some((dir, deps)) = table.get(&name) else {
            problems.push(format!("{name} ({m}): no row in the package table"));
            continue;
        };
        let want_dir = if m == "." { "src/" } else { m.as_str() };
        if !dir.starts_with(want_dir) {
            problems.push(format!(
                "{name}: the table says `{dir}`, the workspace `{m}`"
            ));
        }
        let actual = path_dependencies(&manifest);
        if &actual != deps {
            problems.push(format!(
                "{name}: the table says it depends on {deps:?}, its Cargo.toml on {actual:?}"
            ));
        }
    }
    assert_eq!(
        table.len(),
        members.len(),
        "rows for packages the workspace lacks"
    );
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// The `.rs` files under `dir`, recursively.
fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// The room a file of `src/` belongs to (its first path component, without `.rs`); `None` for
/// the crate root and the binary.
fn room_of(rel: &Path) -> Option<String> {
    let first = rel.components().next()?.as_os_str().to_str()?;
    let room = first.strip_suffix(".rs").unwrap_or(first);
    (room != "lib").then(|| room.to_string())
}

/// What the crate root re-exports (`pub use frame::{Frame, Layout};` → `Frame` → `frame`).
fn root_reexports(lib: &str) -> BTreeMap<String, String> {
    let mut map = BTreeMap::new();
    // A statement may span lines (rustfmt breaks a long list): join the code lines, split at `;`.
    let code: Vec<&str> = lib
        .lines()
        .map(str::trim)
        .filter(|l| !l.starts_with("//") && !l.starts_with('#'))
        .collect();
    for stmt in code.join(" ").split(';') {
        // A `pub use` may follow a `{` or `}` of an inline module (`pub mod pixel { … }`).
        let Some(at) = stmt.find("pub use ") else {
            continue;
        };
        let rest = stmt[at + "pub use ".len()..].trim_end_matches(';');
        let rest = rest.strip_prefix("crate::").unwrap_or(rest);
        let Some((room, names)) = rest.split_once("::") else {
            continue;
        };
        // `model::{A, B}`, `model::fit::{A, B}`: the names in the last braces.
        let names = names
            .rsplit_once('{')
            .map_or(names, |(_, n)| n)
            .trim_end_matches('}');
        for n in names.split(',') {
            let n = n.trim();
            let n = n.rsplit("::").next().unwrap_or(n);
            let n = n.split(" as ").last().unwrap_or(n).trim();
            if !n.is_empty() {
                map.insert(n.to_string(), room.trim().to_string());
            }
        }
    }
    map
}

/// The first path segments after `crate::` in one line of code: `crate::a::b` → `a`,
/// `crate::{a, b::c}` → `a`, `b` (nested braces: only the outer level counts).
fn crate_paths(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    let b = line.as_bytes();
    let mut from = 0;
    while let Some(k) = line[from..].find("crate::") {
        let at = from + k;
        from = at + 7;
        if at > 0 && (b[at - 1].is_ascii_alphanumeric() || b[at - 1] == b'_' || b[at - 1] == b'$') {
            continue;
        }
        let rest = &line[from..];
        if let Some(group) = rest.strip_prefix('{') {
            let mut depth = 0;
            let mut item = String::new();
            let mut expect = true;
            for c in group.chars() {
                match c {
                    '{' => depth += 1,
                    '}' if depth == 0 => break,
                    '}' => depth -= 1,
                    ',' if depth == 0 => expect = true,
                    c if expect && (c.is_alphanumeric() || c == '_') => item.push(c),
                    _ if expect && !item.is_empty() => {
                        out.push(std::mem::take(&mut item));
                        expect = false;
                    }
                    _ => {}
                }
            }
            if !item.is_empty() {
                out.push(item);
            }
        } else {
            let name: String = rest
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            if !name.is_empty() {
                out.push(name);
            }
        }
    }
    out
}

/// Every use of another room: (from, to) → the places (`file:line`).
fn edges() -> BTreeMap<(String, String), Vec<String>> {
    let src = Path::new(ROOT).join("src");
    let lib = std::fs::read_to_string(src.join("lib.rs")).unwrap();
    let reexports = root_reexports(&lib);
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let mut edges: BTreeMap<(String, String), Vec<String>> = BTreeMap::new();
    for f in &files {
        let rel = f.strip_prefix(&src).unwrap();
        let Some(room) = room_of(rel) else { continue };
        for (i, line) in std::fs::read_to_string(f).unwrap().lines().enumerate() {
            if line.trim_start().starts_with("//") {
                continue;
            }
            for name in crate_paths(line) {
                if name == "kit" {
                    continue; // the unit tests' kit (`tests/all/common/kit.rs`), not a room
                }
                let to = reexports.get(&name).cloned().unwrap_or(name);
                if to != room && to != "self" {
                    edges.entry((room.clone(), to)).or_default().push(format!(
                        "src/{}:{}",
                        rel.display(),
                        i + 1
                    ));
                }
            }
        }
    }
    edges
}

#[test]
fn rooms_lean_only_the_way_the_architecture_doc_says() {
    let doc = std::fs::read_to_string(Path::new(ROOT).join("docs/ARCHITECTURE.md")).unwrap();
    let rows = table(&doc);
    assert!(rows.len() >= 10, "the room table has {} rows", rows.len());
    let position: BTreeMap<&str, usize> = rows
        .iter()
        .enumerate()
        .map(|(i, r)| (r.room.as_str(), i))
        .collect();
    let mut problems = Vec::new();

    // Every room of src/ has a row, and every row is a room.
    let mut rooms = BTreeSet::new();
    for e in std::fs::read_dir(Path::new(ROOT).join("src")).unwrap() {
        let p = e.unwrap().path();
        let name = p.file_name().unwrap().to_str().unwrap().to_string();
        if let Some(room) = room_of(Path::new(&name)) {
            if p.is_dir() || name.ends_with(".rs") {
                rooms.insert(room);
            }
        }
    }
    for r in &rooms {
        if !position.contains_key(r.as_str()) {
            problems.push(format!(
                "src/{r}: a room without a row in docs/ARCHITECTURE.md"
            ));
        }
    }
    for r in &rows {
        if !rooms.contains(&r.room) {
            problems.push(format!(
                "`{}`: a row for a room that src/ does not have",
                r.room
            ));
        }
    }

    // The table leans one way: a room may use only rooms above it, unless marked (cycle).
    for (i, r) in rows.iter().enumerate() {
        for (to, cycle) in &r.may_use {
            match position.get(to.as_str()) {
                None => problems.push(format!("`{}` may use `{to}`: no such row", r.room)),
                Some(&j) if j >= i && !cycle => problems.push(format!(
                    "`{}` may use `{to}`, which is below it in the table: mark it (cycle) or fix it",
                    r.room
                )),
                _ => {}
            }
        }
    }

    // The code obeys the table.
    let edges = edges();
    assert!(
        edges.len() > 20,
        "only {} room-to-room uses found: is the parser blind?",
        edges.len()
    );
    for ((from, to), places) in &edges {
        let Some(row) = rows.iter().find(|r| &r.room == from) else {
            continue; // reported above
        };
        if !row.may_use.iter().any(|(m, _)| m == to) {
            problems.push(format!(
                "`{from}` uses `{to}`, which docs/ARCHITECTURE.md does not allow: {}",
                places.join(", ")
            ));
        }
    }
    // A (cycle) exception that the code no longer needs is stale.
    for r in &rows {
        for (to, cycle) in &r.may_use {
            if *cycle && !edges.contains_key(&(r.room.clone(), to.clone())) {
                problems.push(format!(
                    "`{}` → `{to}` is marked (cycle) but no longer used: remove the exception",
                    r.room
                ));
            }
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// The parser the check relies on sees plain paths, grouped imports, root re-exports, and not
/// `pub(crate)`, `$crate::` or identifiers that merely end in `crate`.
#[test]
fn crate_path_parser_reads_the_forms_used() {
    assert_eq!(crate_paths("use crate::model::Model;"), ["model"]);
    assert_eq!(
        crate_paths("use crate::{colorimetry::{a, b}, frame::Frame, limits};"),
        ["colorimetry", "frame", "limits"]
    );
    assert_eq!(
        crate_paths("let x = crate::io::read(p).map_err(crate::error::f);"),
        ["io", "error"]
    );
    assert!(crate_paths("pub(crate) fn f() {}").is_empty());
    assert!(crate_paths("$crate::x; mycrate::y").is_empty());
    let map = root_reexports(
        "pub use frame::{Frame, Layout};\npub use model::Model;\npub use model::fit::{\n    fit_with, White as FitWhite,\n};",
    );
    assert_eq!(map["Layout"], "frame");
    assert_eq!(map["Model"], "model");
    assert_eq!(map["fit_with"], "model");
    assert_eq!(map["FitWhite"], "model");
    assert_eq!(
        room_of(Path::new("io/openexr/chunks.rs")).as_deref(),
        Some("io")
    );
    assert_eq!(room_of(Path::new("limits.rs")).as_deref(), Some("limits"));
}

/// `text` with comments, string / raw string / byte string literals and character literals
/// replaced by spaces (newlines kept, so line numbers stay).
fn blank_comments_and_literals(text: &str) -> String {
    let c: Vec<char> = text.chars().collect();
    let mut out = String::with_capacity(text.len());
    let blank = |out: &mut String, from: &[char]| {
        out.extend(from.iter().map(|&ch| if ch == '\n' { '\n' } else { ' ' }))
    };
    let ident = |ch: char| ch.is_alphanumeric() || ch == '_';
    let mut i = 0;
    while i < c.len() {
        let at = |k: usize| c.get(k).copied().unwrap_or('\0');
        // The prefix of a byte literal (b'x', b"x") is no identifier before the quote.
        let ident_before =
            i > 0 && ident(c[i - 1]) && !(c[i - 1] == 'b' && (i < 2 || !ident(c[i - 2])));
        let end = if at(i) == '/' && at(i + 1) == '/' {
            i + c[i..].iter().take_while(|&&ch| ch != '\n').count()
        } else if at(i) == '/' && at(i + 1) == '*' {
            let (mut j, mut depth) = (i, 0);
            while j < c.len() {
                if at(j) == '/' && at(j + 1) == '*' {
                    depth += 1;
                    j += 2;
                } else if at(j) == '*' && at(j + 1) == '/' {
                    depth -= 1;
                    j += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    j += 1;
                }
            }
            j
        } else if !ident_before && (at(i) == 'r' || (at(i) == 'b' && at(i + 1) == 'r')) && {
            let s = i + if at(i) == 'b' { 2 } else { 1 };
            let hashes = c[s..].iter().take_while(|&&h| h == '#').count();
            at(s + hashes) == '"'
        } {
            // A raw string: r"…", r#"…"#, br"…", ended by `"` and as many `#`.
            let s = i + if at(i) == 'b' { 2 } else { 1 };
            let hashes = c[s..].iter().take_while(|&&h| h == '#').count();
            let mut j = s + hashes + 1;
            while j < c.len() && !(at(j) == '"' && (1..=hashes).all(|h| at(j + h) == '#')) {
                j += 1;
            }
            j + 1 + hashes
        } else if at(i) == '"' {
            let mut j = i + 1;
            while j < c.len() && at(j) != '"' {
                j += if at(j) == '\\' { 2 } else { 1 };
            }
            j + 1
        } else if at(i) == '\'' && !ident_before && at(i + 1) == '\\' {
            // An escaped character: '\n', '\'', '\u{1F600}'.
            i + 3
                + c[(i + 3).min(c.len())..]
                    .iter()
                    .take_while(|&&ch| ch != '\'')
                    .count()
                + 1
        } else if at(i) == '\'' && !ident_before && at(i + 2) == '\'' {
            i + 3
        } else {
            // Code, a lifetime's quote included.
            out.push(c[i]);
            i += 1;
            continue;
        };
        let end = end.min(c.len());
        blank(&mut out, &c[i..end]);
        i = end;
    }
    out
}

/// The public surface stays curated, a budget per crate: the lines that declare an item with
/// plain `pub` (`docs/ARCHITECTURE.md`, "The public surface, counted": the same rule as its
/// `grep`). The corrector's budget is what the command line and the embedders use (the split
/// into crates made public what the binary took from inside the library); the command-line
/// crate exports its entry point only; the Python bindings export nothing to Rust (their API is
/// the Python module). (430: the f32 guard's second evaluator, the GPU shader, is an extension
/// point: `F32Evaluator`, `gpu::ShaderCheck`; and `FastModel::apply_slices`, the kernels on a
/// caller's buffers, and `CaptureFrame::from_frame`, a chart read from an array: both for the
/// bindings. 435: the exports' in-memory forms, `nsrm_export::{render, Rendered}`, `dcp::render` and
/// `icc::render`, so that an embedder gets bytes without an output session. 448: the batch
/// executor moved from the command line into `nsrm_io::batch`, 13 declarations: `execute`, its
/// options, events, outcomes, errors and timing, the `Correct` trait and `ModelCorrector` with
/// its `cpu` and `gpu` constructors, and their re-export. 449: `Reference::builtin_names`, the
/// charts' references for the studio's choice and `--chart auto`. 434: the output session moved
/// out into `nsrm-output` (its own budget), the three `export_to` and `Written` gone; added the
/// `WriteSeek` trait, `FrameSink` with its `Encoder` and the plain `Files` sink, `layout_json`,
/// and `nsrm_io::file_kind` and `nsrm_io::file_id` (one per platform), which the session shares with the
/// batch planner instead of keeping twins. The rooms as crates: the corrector 279 (278, then
/// `FastModel::apply_baseline` for farms that need the same bits on every host), `nsrm-io` 77,
/// `nsrm-chart` 103, `nsrm-export` 39, 498 in all, the 63 more being what the rooms took
/// from inside the core, now its documented API: docs/ARCHITECTURE.md.)
const PUBLIC_BUDGETS: [(&str, usize); 7] = [
    ("src", 279),
    ("crates/nsrm-io/src", 77),
    ("crates/nsrm-chart/src", 103),
    ("crates/nsrm-export/src", 39),
    ("crates/nsrm-output/src", 22),
    ("crates/nsrm-cli/src", 1),
    ("crates/nsrm-py/src", 0),
];

/// Whether `line` declares an item with plain `pub` visibility, as the documented `grep -E
/// '^\s*pub (async |unsafe |const )?(fn|struct|enum|trait|type|const|static|mod|use) '` reads it.
fn declares_public_item(line: &str) -> bool {
    let Some(rest) = line.trim_start().strip_prefix("pub ") else {
        return false;
    };
    let rest = ["async ", "unsafe ", "const "]
        .iter()
        .find_map(|q| rest.strip_prefix(q))
        .unwrap_or(rest);
    [
        "fn ", "struct ", "enum ", "trait ", "type ", "const ", "static ", "mod ", "use ",
    ]
    .iter()
    .any(|k| rest.starts_with(k))
}

#[test]
fn public_declarations_stay_under_the_aim() {
    assert!(declares_public_item("    pub fn f() {}"));
    assert!(declares_public_item("pub const fn f() {}"));
    assert!(declares_public_item("pub use self::{a, b};"));
    assert!(!declares_public_item("pub(crate) fn f() {}"));
    assert!(!declares_public_item("    pub field: u8,"));
    for (dir, budget) in PUBLIC_BUDGETS {
        let mut files = Vec::new();
        rust_files(&Path::new(ROOT).join(dir), &mut files);
        let mut count = 0;
        for f in &files {
            let text = std::fs::read_to_string(f).unwrap();
            count += text.lines().filter(|l| declares_public_item(l)).count();
        }
        eprintln!("{count} public declarations in {dir}");
        assert!(
            count <= budget,
            "{count} public declarations in {dir} (budget: {budget}): make what only the crate \
             uses pub(crate), or move the test that needs it beside the code"
        );
    }
}

/// No process-wide mutable state in the library: no `static mut`, no `thread_local!`, no static
/// lock, cell or atomic (a command's state lives in its values: the output session, the batch
/// plan). Caches of constant data built once (`OnceLock` of the colour-matching functions) are
/// not state.
#[test]
fn the_library_keeps_no_process_wide_mutable_state() {
    let mut files = Vec::new();
    for dir in LIBRARY_DIRS {
        rust_files(&Path::new(ROOT).join(dir), &mut files);
    }
    files.sort();
    let mut found = Vec::new();
    for f in &files {
        let text = blank_comments_and_literals(&std::fs::read_to_string(f).unwrap());
        for (i, line) in text.lines().enumerate() {
            let t = line.trim_start();
            let is_static = t.starts_with("static ") || t.contains(" static ");
            let mutable = ["Mutex", "RwLock", "RefCell", "Cell<", "Atomic"]
                .iter()
                .any(|k| t.contains(k));
            if t.contains("static mut ") || t.contains("thread_local!") || (is_static && mutable) {
                let rel = f.strip_prefix(ROOT).unwrap().display().to_string();
                found.push(format!("{rel}:{}: {}", i + 1, t));
            }
        }
    }
    assert!(
        found.is_empty(),
        "process-wide state:\n{}",
        found.join("\n")
    );
}

/// No source file of any crate is over 1,000 lines without its reason at its top (a "Why
/// one file" paragraph in its module documentation); tests beside the code count as files.
#[test]
fn long_files_say_why_they_are_one_file() {
    let mut long = Vec::new();
    for dir in LIBRARY_DIRS
        .iter()
        .chain(&["crates/nsrm-cli/src", "crates/nsrm-py/src"])
    {
        let mut files = Vec::new();
        rust_files(&Path::new(ROOT).join(dir), &mut files);
        for f in files {
            let text = std::fs::read_to_string(&f).unwrap();
            let n = text.lines().count();
            let head: String = text.lines().take(40).collect::<Vec<_>>().join("\n");
            if n > 1000 && !head.contains("Why one file") {
                long.push(format!("{} ({n} lines)", f.display()));
            }
        }
    }
    assert!(
        long.is_empty(),
        "split these at their seams, or say at the top why each is one file: {long:?}"
    );
}

/// The library crates' messages name no flag of the binary (`--layer`, `--corners`, …): a scan
/// of every non-comment line of their sources (another program's flag, `sbatch --array`, is
/// allowed). A front end names its own flags (the command line's table of parameter → flag).
#[test]
fn library_messages_name_no_flags() {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        for e in std::fs::read_dir(dir).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                walk(&p, out);
            } else if p.extension().is_some_and(|x| x == "rs")
                // A room's unit tests in their own file (`ocio_tests.rs`) run programs
                // with flags; they print no library message.
                && !p.file_stem().is_some_and(|s| s.to_string_lossy().ends_with("_tests"))
            {
                out.push(p);
            }
        }
    }
    let mut files = Vec::new();
    for dir in LIBRARY_DIRS {
        walk(&Path::new(ROOT).join(dir), &mut files);
    }
    assert!(files.len() > 30, "{} files", files.len());
    let mut found = Vec::new();
    for f in &files {
        // A file's unit-test module (`mod tests {`, last in the file) holds no library message.
        let text = std::fs::read_to_string(f).unwrap();
        let lines = text.lines().take_while(|l| l.trim() != "mod tests {");
        for (i, line) in lines.enumerate() {
            let code = line.trim_start();
            if code.starts_with("//") || line.contains("sbatch --") {
                continue;
            }
            let b = code.as_bytes();
            let flag = (0..b.len().saturating_sub(2)).any(|k| {
                b[k] == b'-'
                    && b[k + 1] == b'-'
                    && b[k + 2].is_ascii_lowercase()
                    && (k == 0 || !(b[k - 1].is_ascii_alphanumeric() || b[k - 1] == b'-'))
            });
            if flag {
                found.push(format!("{}:{}: {}", f.display(), i + 1, code));
            }
        }
    }
    assert!(
        found.is_empty(),
        "flag names in library code:\n{}",
        found.join("\n")
    );
}
