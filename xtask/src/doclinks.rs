//! The `docs` step of `cargo xtask test`: every relative link and image in the project's Markdown
//! files (`*.md` at the root and under `docs/`) points to a file or directory that exists, so
//! the README's and the docs' figures and cross-references cannot silently break.
//!
//! A link is the `(target)` after `](` in inline Markdown links and images; web links
//! (`scheme://`, `mailto:`) and pure anchors (`#...`) are skipped, a `#fragment` is ignored, and
//! the target is resolved relative to the file that contains it.

use crate::util::Ctx;
use anyhow::{bail, Context, Result};
use std::path::{Path, PathBuf};

/// Checks the links; fails listing every broken one as `file:line: target`.
pub fn check(ctx: &Ctx) -> Result<()> {
    let mut files = markdown_in(&ctx.root)?;
    let docs = ctx.root.join("docs");
    if docs.is_dir() {
        files.extend(markdown_in(&docs)?);
    }
    let mut broken = Vec::new();
    let mut count = 0;
    for file in &files {
        let text = std::fs::read_to_string(file)
            .with_context(|| format!("cannot read {}", file.display()))?;
        let dir = file.parent().unwrap_or(&ctx.root);
        for (line_no, line) in text.lines().enumerate() {
            for target in link_targets(line) {
                count += 1;
                if !dir.join(target).exists() {
                    let shown = file.strip_prefix(&ctx.root).unwrap_or(file);
                    broken.push(format!("{}:{}: {target}", shown.display(), line_no + 1));
                }
            }
        }
    }
    if !broken.is_empty() {
        bail!("broken links in Markdown files:\n  {}", broken.join("\n  "));
    }
    println!(
        "{count} relative links in {} Markdown files resolve",
        files.len()
    );
    Ok(())
}

fn markdown_in(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .with_context(|| format!("cannot list {}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file() && p.extension().is_some_and(|e| e == "md"))
        .collect();
    files.sort();
    Ok(files)
}

/// Relative link targets on one line, without `#fragment`s.
fn link_targets(line: &str) -> Vec<&str> {
    let mut out = Vec::new();
    let mut rest = line;
    while let Some(pos) = rest.find("](") {
        rest = &rest[pos + 2..];
        let Some(end) = rest.find(')') else { break };
        // `[text](target "title")`: the target ends at the first space.
        let target = rest[..end].split_whitespace().next().unwrap_or("");
        let target = target.split('#').next().unwrap_or("");
        let external = target.contains("://") || target.starts_with("mailto:");
        if !target.is_empty() && !external {
            out.push(target);
        }
        rest = &rest[end..];
    }
    out
}

#[cfg(test)]
mod tests {
    use super::link_targets;

    #[test]
    fn finds_relative_targets_only() {
        let line = "see [a](docs/params.md#schema), ![img](docs/img/loops.png \"t\") and \
                    [web](https://example.org) [anchor](#top) [m](mailto:x@y)";
        assert_eq!(
            link_targets(line),
            vec!["docs/params.md", "docs/img/loops.png"]
        );
        assert!(link_targets("no links (here)").is_empty());
    }
}
