//! The documentation stays true to the repository: every relative link in README.md and
//! docs/*.md resolves (the file or directory exists; an `#anchor` into a Markdown page names one
//! of its headings as GitHub slugs them), the README's viewer key table is `view::hud::KEYS`,
//! and `relit --help` lists the same keys. No device needed.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// README.md and every Markdown page in docs/.
fn pages() -> Vec<PathBuf> {
    let root = Path::new(ROOT);
    let mut v = vec![root.join("README.md")];
    let mut docs: Vec<PathBuf> = std::fs::read_dir(root.join("docs"))
        .expect("docs/")
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    docs.sort();
    v.extend(docs);
    v
}

/// The page's lines outside fenced code blocks, with HTML comments removed.
fn prose_lines(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut fence: Option<String> = None;
    let mut in_comment = false;
    for line in text.lines() {
        let t = line.trim_start();
        if let Some(f) = &fence {
            if t.starts_with(f.as_str())
                && t.trim_end().chars().all(|c| c == f.as_bytes()[0] as char)
            {
                fence = None;
            }
            out.push(String::new());
            continue;
        }
        if t.starts_with("```") || t.starts_with("~~~") {
            let c = t.chars().next().unwrap();
            fence = Some(t.chars().take_while(|&x| x == c).collect());
            out.push(String::new());
            continue;
        }
        // HTML comments, possibly over several lines.
        let mut kept = String::new();
        let mut rest = line;
        loop {
            if in_comment {
                match rest.find("-->") {
                    Some(e) => {
                        rest = &rest[e + 3..];
                        in_comment = false;
                    }
                    None => break,
                }
            } else {
                match rest.find("<!--") {
                    Some(s) => {
                        kept.push_str(&rest[..s]);
                        rest = &rest[s + 4..];
                        in_comment = true;
                    }
                    None => {
                        kept.push_str(rest);
                        break;
                    }
                }
            }
        }
        out.push(kept);
    }
    out
}

/// A line without its inline code spans (a run of n backticks up to the next run of n).
fn without_code(line: &str) -> String {
    let b = line.as_bytes();
    let mut out = String::new();
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'`' {
            let n = b[i..].iter().take_while(|&&c| c == b'`').count();
            let mut j = i + n;
            let mut close = None;
            while j < b.len() {
                if b[j] == b'`' {
                    let m = b[j..].iter().take_while(|&&c| c == b'`').count();
                    if m == n {
                        close = Some(j + m);
                        break;
                    }
                    j += m;
                } else {
                    j += 1;
                }
            }
            match close {
                Some(e) => {
                    out.push(' ');
                    i = e;
                }
                None => {
                    out.push_str(&line[i..i + n]);
                    i += n;
                }
            }
        } else {
            let c = line[i..].chars().next().unwrap();
            out.push(c);
            i += c.len_utf8();
        }
    }
    out
}

/// The targets of a line's inline links and images, `[text](target "title")`, and of a
/// reference definition `[label]: target`.
fn link_targets(line: &str) -> Vec<String> {
    let mut v = Vec::new();
    let mut rest = line;
    while let Some(s) = rest.find("](") {
        let after = &rest[s + 2..];
        let mut depth = 0;
        let mut end = after.len();
        for (k, c) in after.char_indices() {
            match c {
                '(' => depth += 1,
                ')' if depth == 0 => {
                    end = k;
                    break;
                }
                ')' => depth -= 1,
                _ => {}
            }
        }
        let inner = after[..end].trim();
        let target = inner
            .strip_prefix('<')
            .and_then(|t| t.split_once('>').map(|(t, _)| t))
            .unwrap_or_else(|| inner.split_whitespace().next().unwrap_or(""));
        v.push(target.to_string());
        rest = &after[end.min(after.len())..];
    }
    let t = line.trim_start();
    if t.starts_with('[') {
        if let Some((label, target)) = t.split_once("]:") {
            if !label.contains('(') {
                if let Some(target) = target.split_whitespace().next() {
                    v.push(target.to_string());
                }
            }
        }
    }
    v
}

/// GitHub's anchor for a heading's text: lower case, everything but letters, digits, spaces,
/// hyphens and underscores removed, spaces turned into hyphens (github-slugger).
fn slug(heading: &str) -> String {
    // A link in a heading shows its text.
    let mut text = String::new();
    let mut rest = heading;
    while let Some(s) = rest.find("](") {
        text.push_str(&rest[..s]);
        let after = &rest[s + 2..];
        rest = after.find(')').map_or("", |e| &after[e + 1..]);
    }
    text.push_str(rest);
    text.trim()
        .to_lowercase()
        .chars()
        .filter(|c| c.is_alphanumeric() || matches!(c, ' ' | '-' | '_'))
        .map(|c| if c == ' ' { '-' } else { c })
        .collect()
}

/// The anchors of a Markdown page's headings; a repeated slug gets -1, -2, … as on GitHub.
fn anchors(text: &str) -> Vec<String> {
    let mut seen: HashMap<String, usize> = HashMap::new();
    let mut out = Vec::new();
    for line in prose_lines(text) {
        let hashes = line.chars().take_while(|&c| c == '#').count();
        if !(1..=6).contains(&hashes) || !line[hashes..].starts_with(' ') {
            continue;
        }
        let title = line[hashes..].trim().trim_end_matches('#').trim_end();
        let base = slug(title);
        let mut s = base.clone();
        while seen.contains_key(&s) {
            let n = seen.get_mut(&base).unwrap();
            *n += 1;
            s = format!("{base}-{n}");
        }
        seen.insert(s.clone(), 0);
        out.push(s);
    }
    out
}

/// Percent-escapes in a link target (`%20` and the like).
fn unescape(t: &str) -> String {
    let b = t.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' && i + 2 < b.len() && b[i + 1..i + 3].iter().all(u8::is_ascii_hexdigit) {
            let hex = std::str::from_utf8(&b[i + 1..i + 3]).unwrap();
            out.push(u8::from_str_radix(hex, 16).unwrap());
            i += 3;
            continue;
        }
        out.push(b[i]);
        i += 1;
    }
    String::from_utf8(out).unwrap()
}

/// Why a link from `page` to `target` does not resolve, or None.
fn broken(page: &Path, target: &str) -> Option<String> {
    if target.is_empty() {
        return Some("an empty link".into());
    }
    if target.contains("://") || target.starts_with("mailto:") {
        return None;
    }
    if target.starts_with('/') {
        return Some("an absolute path (it does not resolve in a clone)".into());
    }
    let (path, anchor) = match target.split_once('#') {
        Some((p, a)) => (p, Some(a)),
        None => (target, None),
    };
    let file = if path.is_empty() {
        page.to_path_buf()
    } else {
        page.parent().unwrap().join(unescape(path))
    };
    if !file.exists() {
        return Some(format!("{} does not exist", file.display()));
    }
    let anchor = anchor?;
    if file.extension().is_none_or(|e| e != "md") {
        return None; // anchors into source files (line numbers) are not checked
    }
    let text = std::fs::read_to_string(&file).unwrap();
    let all = anchors(&text);
    if all.iter().any(|a| a == &unescape(anchor)) {
        None
    } else {
        Some(format!(
            "{} has no heading with the anchor #{anchor} (its anchors: {})",
            file.display(),
            all.join(", ")
        ))
    }
}

#[test]
fn every_relative_link_in_the_readme_and_docs_resolves() {
    let mut bad = Vec::new();
    let mut count = 0;
    for page in pages() {
        let text = std::fs::read_to_string(&page).unwrap();
        for (n, line) in prose_lines(&text).iter().enumerate() {
            for target in link_targets(&without_code(line)) {
                count += 1;
                if let Some(why) = broken(&page, &target) {
                    let name = page.strip_prefix(ROOT).unwrap().display();
                    bad.push(format!("{name}:{}: ({target}): {why}", n + 1));
                }
            }
        }
    }
    assert!(count > 20, "found only {count} links: the scan is broken");
    assert!(bad.is_empty(), "broken links:\n{}", bad.join("\n"));
}

#[test]
fn the_link_checker_knows_githubs_anchors_and_skips_code() {
    assert_eq!(
        slug("2026-12-03, session 14: a real capture, AliceVision's buddha"),
        "2026-12-03-session-14-a-real-capture-alicevisions-buddha"
    );
    assert_eq!(slug("The bake (§4.1–4.2)"), "the-bake-4142");
    assert_eq!(
        slug("Real captures (`tools/capture/`)"),
        "real-captures-toolscapture"
    );
    assert_eq!(
        slug("See [the map](docs/design.md) first"),
        "see-the-map-first"
    );
    assert_eq!(
        anchors("# A\n## A\n```\n# not a heading\n```\n### A\n"),
        ["a", "a-1", "a-2"]
    );
    let line = without_code("a [x](one.md) and `[y](two.md)` and ``[z](`three`)``");
    assert_eq!(link_targets(&line), ["one.md"]);
    assert_eq!(
        link_targets("![p](pic.jpg \"title\") [q](<a b.md>)"),
        ["pic.jpg", "a b.md"]
    );
    assert_eq!(link_targets("[ref]: docs/x.md"), ["docs/x.md"]);
    assert!(prose_lines("<!-- [a](gone.md)\n[b](gone.md) -->\nok")
        .iter()
        .all(|l| !l.contains("gone")));
    let readme = Path::new(ROOT).join("README.md");
    assert!(broken(&readme, "docs/design.md").is_none());
    assert!(broken(&readme, "docs/no-such-page.md").is_some());
    assert!(broken(&readme, "#viewer-keys").is_none());
    assert!(broken(&readme, "#no-such-heading").is_some());
    assert!(broken(&readme, "https://example.org/x").is_none());
}

/// The README's viewer key table, (key, what it does) per row.
fn readme_keys() -> Vec<(String, String)> {
    let text = std::fs::read_to_string(Path::new(ROOT).join("README.md")).unwrap();
    let start = text
        .find("\n### Viewer keys\n")
        .expect("README: a \"### Viewer keys\" section");
    let section = &text[start + 1..];
    let end = section[4..].find("\n#").map_or(section.len(), |e| e + 4);
    section[..end]
        .lines()
        .filter_map(|l| l.strip_prefix("| `"))
        .map(|row| {
            let (key, rest) = row.split_once("` | ").expect("| `KEY` | WHAT |");
            let what = rest.strip_suffix(" |").expect("a row ends with \" |\"");
            (key.to_string(), what.to_string())
        })
        .collect()
}

#[test]
fn the_readme_viewer_keys_are_the_hud_key_list() {
    let want: Vec<(String, String)> = relit_engine::view::hud::KEYS
        .iter()
        .map(|(k, w)| (k.to_string(), w.to_string()))
        .collect();
    let rows: String = want
        .iter()
        .map(|(k, w)| format!("| `{k}` | {w} |\n"))
        .collect();
    assert_eq!(
        readme_keys(),
        want,
        "README's \"### Viewer keys\" table differs from view::hud::KEYS; its rows should be:\n{rows}"
    );
}

#[test]
fn relit_help_lists_the_viewer_keys() {
    let relit = env!("CARGO_BIN_EXE_relit");
    for args in [&["--help"][..], &["view", "--help"]] {
        let out = std::process::Command::new(relit)
            .args(args)
            .output()
            .unwrap();
        assert!(out.status.success(), "relit {args:?}: {out:?}");
        let text = String::from_utf8(out.stdout).unwrap();
        for line in relit_engine::view::hud::key_lines() {
            assert!(
                text.contains(&line),
                "relit {args:?} lacks the key line {line:?}:\n{text}"
            );
        }
        assert!(
            !text.contains("network/ULR/ratio"),
            "relit {args:?}: an old key list"
        );
    }
}

/// The repository keeps at most one training checkpoint (a run in progress's, .gitignore), so
/// that checkpoint versions stop accumulating in history; finished runs keep theirs in history
/// or a data folder.
#[test]
fn at_most_one_training_checkpoint_is_tracked() {
    let out = std::process::Command::new("git")
        .args(["ls-files", "--", "tools/train/runs"])
        .current_dir(ROOT)
        .output()
        .expect("git runs");
    assert!(out.status.success(), "git ls-files: {out:?}");
    let text = String::from_utf8(out.stdout).unwrap();
    let tracked: Vec<&str> = (text.lines())
        .filter(|f| f.ends_with(".pt") || f.ends_with(".safetensors"))
        .collect();
    assert!(tracked.len() <= 1, "tracked checkpoints: {tracked:?}");
}
