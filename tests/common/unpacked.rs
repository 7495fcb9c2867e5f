//! Vulkan drivers unpacked beside the installed one by a script (never installed), chosen with
//! the loader's `VK_DRIVER_FILES` from the `env` file the script writes: Debian 12's own lavapipe
//! (`scripts/stock-mesa.sh`) and SwiftShader (`scripts/swiftshader.sh`). Without the unpacked
//! driver a test fails, saying which script to run; it never skips.

use std::path::PathBuf;

/// One unpacking script's folder and what to tell a user who has not run it.
pub struct Unpacked {
    /// The variable that moves the folder (`TRILAB_STOCK_MESA`).
    pub dir_var: &'static str,
    /// The folder under `~/.cache/trilab/` otherwise.
    pub default_dir: &'static str,
    /// `scripts/stock-mesa.sh`.
    pub script: &'static str,
    /// What the script fetches, for the message ("mesa-vulkan-drivers from bookworm").
    pub what: &'static str,
}

pub const STOCK_MESA: Unpacked = Unpacked {
    dir_var: "TRILAB_STOCK_MESA",
    default_dir: "stock-mesa",
    script: "scripts/stock-mesa.sh",
    what: "Debian 12's own lavapipe (mesa-vulkan-drivers from bookworm)",
};

pub const SWIFTSHADER: Unpacked = Unpacked {
    dir_var: "TRILAB_SWIFTSHADER",
    default_dir: "swiftshader",
    script: "scripts/swiftshader.sh",
    what: "SwiftShader (the Vulkan driver in chromium-common)",
};

impl Unpacked {
    /// The folder the script unpacks into.
    pub fn dir(&self) -> PathBuf {
        match std::env::var_os(self.dir_var) {
            Some(d) => PathBuf::from(d),
            None => PathBuf::from(std::env::var_os("HOME").expect("HOME is set"))
                .join(".cache/trilab")
                .join(self.default_dir),
        }
    }

    /// The variables that select the driver (`VK_DRIVER_FILES`, and `LD_LIBRARY_PATH` where the
    /// script unpacked libraries too), from the script's `env` file.
    pub fn env(&self) -> Vec<(String, String)> {
        let file = self.dir().join("env");
        let text = std::fs::read_to_string(&file).unwrap_or_else(|e| {
            panic!(
                "{} is not unpacked ({}: {e}): run `{}` (it downloads the package and unpacks it there; never \
                 installs; install-deps.sh runs it)",
                self.what,
                file.display(),
                self.script
            )
        });
        let vars: Vec<(String, String)> =
            text.lines().filter_map(|l| l.split_once('=')).map(|(k, v)| (k.to_owned(), v.to_owned())).collect();
        match vars.iter().find(|(k, _)| k == "VK_DRIVER_FILES") {
            Some((_, icd)) if PathBuf::from(icd).is_file() => vars,
            _ => panic!("{} names no ICD file that exists: run `{}` again", file.display(), self.script),
        }
    }

    /// `trilab args` on this driver; panics past `timeout_s`.
    pub fn run(&self, args: &[&str], timeout_s: u64) -> std::process::Output {
        let vars = self.env();
        let env: Vec<(&str, &str)> = vars.iter().map(|(k, v)| (k.as_str(), v.as_str())).collect();
        super::cli::run(args, None, &env, timeout_s).0
    }

    /// `trilab devices` on this driver: its text, after checking that it ran and that the text
    /// names the driver (`names`, e.g. "Mesa 22.3.6").
    pub fn devices(&self, names: &str) -> String {
        let o = self.run(&["devices"], 60);
        let err = super::cli::ok(&o);
        let text = String::from_utf8_lossy(&o.stdout).into_owned();
        assert!(text.contains(names), "not {}:\n{text}\n{err}", self.what);
        text
    }

    /// `trilab args --json` on this driver, its report parsed, after checking that it ran.
    pub fn json(&self, args: &[&str], timeout_s: u64) -> serde_json::Value {
        let o = self.run(&[args, &["--json"]].concat(), timeout_s);
        let err = super::cli::ok(&o);
        serde_json::from_slice(&o.stdout).unwrap_or_else(|e| panic!("{e}: {err}"))
    }
}
