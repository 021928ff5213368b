//! Provides what a fresh machine lacks: thumb targets (rustup) and QEMU (apt-get), without
//! ever removing a package the user has installed.

use anyhow::{bail, Context, Result};
use std::path::{Path, PathBuf};
use std::process::Command;

use crate::board;
use crate::cmd::{describe, run_status, target_dir, workspace_root};

/// Installs the thumb targets that `rustup` reports missing for the workspace toolchain.
pub fn ensure_targets() -> Result<()> {
    let output = Command::new("rustup")
        .args(["target", "list", "--installed"])
        .current_dir(workspace_root())
        .output()
        .context("running `rustup target list --installed` (is rustup installed?)")?;
    let installed = String::from_utf8_lossy(&output.stdout);
    let missing: Vec<_> = board::all_targets()
        .into_iter()
        .filter(|t| !installed.lines().any(|l| l.trim() == *t))
        .collect();
    if missing.is_empty() {
        return Ok(());
    }
    eprintln!("xtask: installing Rust targets {}", missing.join(", "));
    let mut cmd = Command::new("rustup");
    cmd.args(["target", "add"]).args(&missing);
    run_status(&mut cmd).context("`rustup target add` failed")
}

/// The Debian package that provides the emulator.
const QEMU_PACKAGE: &str = "qemu-system-arm";

/// Set to `1` to use a private copy of QEMU unpacked under `target/qemu/` even when the
/// system package could be installed (what happens anyway when installing it would remove
/// another package).
const PRIVATE_ENV: &str = "XTASK_QEMU_PRIVATE";

/// Makes sure `qemu-system-arm` runs, in this order:
/// 1. the one on PATH;
/// 2. a private copy unpacked earlier into `target/qemu/` (put first on PATH for this
///    process and every child: cargo tests, `vsa --qemu`);
/// 3. as root with apt-get: `apt-get install` when the simulated install removes nothing,
///    otherwise (e.g. a newer `qemu-utils` than Debian's QEMU accepts) the packages are
///    downloaded with `apt-get download` and unpacked into `target/qemu/` with
///    `dpkg-deb -x`: the system's packages are never touched;
/// 4. otherwise stops with the exact command to run.
pub fn ensure_qemu() -> Result<()> {
    let private = std::env::var(PRIVATE_ENV).is_ok_and(|v| v == "1");
    if !private && qemu_version().is_some() {
        return Ok(());
    }
    let wrapper = client::qemu::private_qemu(&target_dir());
    if wrapper.exists() {
        put_first_on_path(wrapper.parent().expect("bin/ has a parent"))?;
        if qemu_version().is_some() {
            return Ok(());
        }
    }
    let install = format!(
        "apt-get update && apt-get install -y --no-install-recommends --no-remove {QEMU_PACKAGE}"
    );
    let is_root = crate::cmd::is_root();
    let has_apt = Command::new("apt-get").arg("--version").output().is_ok();
    if !(is_root && has_apt) {
        bail!(
            "{QEMU_PACKAGE} is not installed. Install it with:\n    sudo sh -c '{install}'\n\
             (or your distribution's QEMU ARM system emulator package), then run this again.\n\
             If apt-get refuses because it would remove a package, run this command as root:\n\
             it then unpacks a private QEMU into target/qemu/ without changing the system."
        );
    }
    eprintln!("xtask: {QEMU_PACKAGE} is missing; asking apt-get what installing it takes");
    run_status(Command::new("apt-get").arg("update")).context("`apt-get update` failed")?;
    let plan = simulate_install()?;
    if plan.removals.is_empty() && !private {
        eprintln!("xtask: installing {QEMU_PACKAGE} with apt-get (nothing is removed)");
        run_status(
            Command::new("apt-get")
                .args([
                    "install",
                    "-y",
                    "--no-install-recommends",
                    "--no-remove",
                    QEMU_PACKAGE,
                ])
                .env("DEBIAN_FRONTEND", "noninteractive"),
        )
        .with_context(|| format!("`apt-get install {QEMU_PACKAGE}` failed"))?;
    } else {
        if !plan.removals.is_empty() {
            eprintln!(
                "xtask: `apt-get install {QEMU_PACKAGE}` would remove {}; unpacking a private \
                 QEMU into {} instead (installed packages stay as they are)",
                plan.removals.join(", "),
                private_root().display()
            );
        }
        let mut packages = plan.installs;
        if !packages.iter().any(|p| p == QEMU_PACKAGE) {
            // Already installed system-wide (the forced private copy): its libraries are
            // there, only QEMU's own packages are unpacked.
            packages.extend(
                [QEMU_PACKAGE, "qemu-system-common", "qemu-system-data"].map(str::to_owned),
            );
        }
        unpack_private(&packages)?;
        put_first_on_path(wrapper.parent().expect("bin/ has a parent"))?;
    }
    match qemu_version() {
        Some(v) => {
            eprintln!("xtask: using {v}");
            Ok(())
        }
        None => bail!("{QEMU_PACKAGE} still does not run after installing it"),
    }
}

/// What `apt-get install --simulate` would do.
#[derive(Debug, Default, PartialEq)]
struct InstallPlan {
    /// Packages it would install (name only).
    installs: Vec<String>,
    /// Packages it would remove.
    removals: Vec<String>,
}

fn simulate_install() -> Result<InstallPlan> {
    let mut cmd = Command::new("apt-get");
    cmd.args([
        "install",
        "--simulate",
        "--no-install-recommends",
        QEMU_PACKAGE,
    ]);
    let out = cmd
        .output()
        .with_context(|| format!("running {}", describe(&cmd)))?;
    if !out.status.success() {
        bail!(
            "{} failed:\n{}",
            describe(&cmd),
            String::from_utf8_lossy(&out.stderr)
        );
    }
    Ok(parse_plan(&String::from_utf8_lossy(&out.stdout)))
}

/// Reads the `Inst NAME …` and `Remv NAME …` lines of a simulated apt-get run.
fn parse_plan(text: &str) -> InstallPlan {
    let mut plan = InstallPlan::default();
    for line in text.lines() {
        let mut words = line.split_whitespace();
        let (Some(verb), Some(name)) = (words.next(), words.next()) else {
            continue;
        };
        match verb {
            "Inst" => plan.installs.push(name.to_owned()),
            "Remv" => plan.removals.push(name.to_owned()),
            _ => {}
        }
    }
    plan
}

/// `target/qemu/`: the private QEMU (`debs/`, the unpacked `root/`, the `bin/` wrapper).
fn private_root() -> PathBuf {
    client::qemu::private_qemu_root(&target_dir())
}

/// Downloads `packages` and unpacks them under `target/qemu/root`, then writes
/// `target/qemu/bin/qemu-system-arm`, a wrapper that runs the unpacked binary with the
/// unpacked libraries first on its library path.
fn unpack_private(packages: &[String]) -> Result<()> {
    if !packages.iter().any(|p| p == QEMU_PACKAGE) {
        bail!("apt-get's plan does not install {QEMU_PACKAGE}: {packages:?}");
    }
    let root = private_root();
    let debs = root.join("debs");
    let tree = root.join("root");
    for dir in [&debs, &tree] {
        if dir.exists() {
            std::fs::remove_dir_all(dir).with_context(|| format!("clearing {}", dir.display()))?;
        }
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    run_status(
        Command::new("apt-get")
            .arg("download")
            .args(packages)
            .current_dir(&debs),
    )
    .context("`apt-get download` failed")?;
    for entry in std::fs::read_dir(&debs)? {
        let deb = entry?.path();
        if deb.extension().is_some_and(|e| e == "deb") {
            run_status(Command::new("dpkg-deb").arg("-x").arg(&deb).arg(&tree))
                .with_context(|| format!("unpacking {}", deb.display()))?;
        }
    }
    let lib_dirs = library_dirs(&tree)?;
    // Where `vsa --qemu` looks for it too.
    let wrapper = client::qemu::private_qemu(&target_dir());
    if let Some(bin) = wrapper.parent() {
        std::fs::create_dir_all(bin)?;
    }
    let script = format!(
        "#!/bin/sh\n# Private QEMU unpacked by `cargo xtask` (see docs/qemu.md); the system's packages are untouched.\n\
         LD_LIBRARY_PATH=\"{}${{LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}}\" exec \"{}\" \"$@\"\n",
        lib_dirs.join(":"),
        tree.join("usr/bin").join(client::qemu::QEMU_BINARY).display()
    );
    std::fs::write(&wrapper, script)?;
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&wrapper, std::fs::Permissions::from_mode(0o755))?;
    Ok(())
}

/// The unpacked tree's multiarch library directories (`usr/lib/x86_64-linux-gnu`, …).
fn library_dirs(tree: &Path) -> Result<Vec<String>> {
    let mut dirs = Vec::new();
    for parent in [tree.join("usr/lib"), tree.join("lib")] {
        let Ok(entries) = std::fs::read_dir(&parent) else {
            continue;
        };
        for entry in entries {
            let path = entry?.path();
            if path.is_dir() && path.to_string_lossy().ends_with("-linux-gnu") {
                dirs.push(path.display().to_string());
            }
        }
    }
    dirs.sort();
    Ok(dirs)
}

/// Puts `dir` first on PATH for this process and the children it starts.
fn put_first_on_path(dir: &Path) -> Result<()> {
    let old = std::env::var_os("PATH").unwrap_or_default();
    let mut paths = vec![dir.to_path_buf()];
    paths.extend(std::env::split_paths(&old).filter(|p| p != dir));
    let joined = std::env::join_paths(paths).context("building PATH")?;
    std::env::set_var("PATH", joined);
    Ok(())
}

/// First line of `qemu-system-arm --version`, if it runs.
pub fn qemu_version() -> Option<String> {
    let out = Command::new(QEMU_PACKAGE).arg("--version").output().ok()?;
    if !out.status.success() {
        return None;
    }
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .next()
        .map(str::to_owned)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Lines as `apt-get install --simulate` prints them on Debian 12 when a newer
    /// qemu-utils is installed.
    #[test]
    fn plan_lists_installs_and_removals() {
        let text = "NOTE: This is only a simulation!\n\
            Reading package lists...\n\
            The following packages will be REMOVED:\n  qemu-utils\n\
            Remv qemu-utils [1:10.0.2+ds-2+deb13u1~bpo12+1]\n\
            Inst libfdt1 (1.6.1-4+b1 Debian:12.12/stable [amd64])\n\
            Inst qemu-system-arm (1:7.2+dfsg-7+deb12u18+b3 Debian:12.12/stable [amd64])\n\
            Conf libfdt1 (1.6.1-4+b1 Debian:12.12/stable [amd64])\n";
        let plan = parse_plan(text);
        assert_eq!(plan.removals, ["qemu-utils"]);
        assert_eq!(plan.installs, ["libfdt1", "qemu-system-arm"]);
    }

    #[test]
    fn plan_without_removals() {
        let plan = parse_plan("Inst qemu-system-arm (1:7.2 Debian [amd64])\n");
        assert!(plan.removals.is_empty());
        assert_eq!(plan.installs, ["qemu-system-arm"]);
    }
}
