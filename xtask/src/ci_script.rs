//! The CI entry point `.ci/run` must at least parse as bash (`bash -n`): a bad merge once
//! left an unterminated backquote in it, and CI failed before running a single test.

use std::path::Path;
use std::process::Command;

use anyhow::{ensure, Context, Result};

use crate::cmd::{describe, workspace_root};

/// The CI script, relative to the workspace root.
pub const CI_SCRIPT: &str = ".ci/run";

/// `bash -n .ci/run` in the workspace root.
pub fn check() -> Result<()> {
    check_syntax(&workspace_root().join(CI_SCRIPT))
}

/// `bash -n script`: bash's own message if it does not parse.
fn check_syntax(script: &Path) -> Result<()> {
    ensure!(script.is_file(), "{} does not exist", script.display());
    let mut cmd = Command::new("bash");
    cmd.arg("-n").arg(script);
    let out = cmd
        .output()
        .with_context(|| format!("starting {}", describe(&cmd)))?;
    ensure!(
        out.status.success(),
        "`{}` exited with {}: {}",
        describe(&cmd),
        out.status,
        String::from_utf8_lossy(&out.stderr).trim()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_unterminated_backquote_is_caught() {
        let dir = std::env::temp_dir().join(format!("vsa-ci-script-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let script = dir.join("run");
        std::fs::write(&script, "#!/usr/bin/env bash\necho ok\n").unwrap();
        let good = check_syntax(&script);
        std::fs::write(&script, "#!/usr/bin/env bash\necho `date\n").unwrap();
        let bad = check_syntax(&script);
        std::fs::remove_dir_all(&dir).unwrap();
        assert!(good.is_ok(), "{good:?}");
        let e = format!("{:#}", bad.unwrap_err());
        assert!(e.contains("bash -n"), "{e}");
        assert!(check_syntax(&dir.join("missing")).is_err());
    }
}
