//! The header a farm task's log starts with: which nsrm, which batch and shard, on which host,
//! with which device asked, and how many frames — what a wrangler reads first in a task's log.

/// This machine's host name: the kernel's (Linux), else `HOSTNAME` or `COMPUTERNAME`, else `?`.
pub(crate) fn host_name() -> String {
    use std::io::Read;
    let mut buf = Vec::new();
    let kernel = std::fs::File::open("/proc/sys/kernel/hostname")
        .and_then(|f| f.take(256).read_to_end(&mut buf))
        .ok()
        .map(|_| String::from_utf8_lossy(&buf).trim().to_string())
        .filter(|n| !n.is_empty());
    kernel
        .or_else(|| std::env::var("HOSTNAME").ok())
        .or_else(|| std::env::var("COMPUTERNAME").ok())
        .unwrap_or_else(|| "?".into())
}

/// What a task's header says.
#[derive(Debug, Clone)]
pub(crate) struct Header<'a> {
    pub batch: Option<&'a str>,
    pub shard: (usize, usize),
    pub host: &'a str,
    /// The task's apply settings (`--device X`, `--adapter=NAME`, …).
    pub settings: &'a [String],
    pub frames: usize,
    pub batch_frames: usize,
}

/// Text for a log: as it is, or quoted with escapes when it holds a control character.
fn shown(s: &str) -> String {
    if s.chars().any(char::is_control) {
        format!("{s:?}")
    } else {
        s.to_string()
    }
}

impl Header<'_> {
    /// The header's lines.
    pub(crate) fn lines(&self) -> Vec<String> {
        let device = self
            .settings
            .windows(2)
            .find(|w| w[0] == "--device")
            .map(|w| w[1].as_str())
            .unwrap_or("auto");
        let adapter = self
            .settings
            .iter()
            .find_map(|w| w.strip_prefix("--adapter="))
            .map(|a| format!(", --adapter {}", shown(a)))
            .unwrap_or_default();
        let jobs = self
            .settings
            .iter()
            .find_map(|w| w.strip_prefix("--jobs="))
            .map(|j| format!(", --jobs {j}"))
            .unwrap_or_default();
        let why = match device {
            "auto" => "the GPU when one opens, else the CPU; apply says which and why",
            "gpu" => "the GPU, or the task fails",
            _ => "the CPU",
        };
        vec![
            format!(
                "nsrm farm run: nsrm {}, batch {}, shard {}/{}, host {} (pid {})",
                env!("CARGO_PKG_VERSION"),
                self.batch.map(shown).unwrap_or_else(|| "(not named)".into()),
                self.shard.0,
                self.shard.1,
                shown(self.host),
                std::process::id()
            ),
            format!(
                "nsrm farm run: {} frame(s) in this shard, of {} in the batch; device asked: --device {device}{adapter}{jobs} ({why})",
                self.frames, self.batch_frames
            ),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_header_names_the_task() {
        let settings: Vec<String> = ["--device", "gpu", "--adapter=RTX\n", "--jobs=4"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        let h = Header {
            batch: Some("nsrm-0123456789ab"),
            shard: (2, 4),
            host: "node17",
            settings: &settings,
            frames: 12,
            batch_frames: 48,
        };
        let l = h.lines();
        assert_eq!(l.len(), 2);
        assert!(
            l[0].contains("batch nsrm-0123456789ab, shard 2/4, host node17 (pid "),
            "{}",
            l[0]
        );
        assert!(l[0].contains(env!("CARGO_PKG_VERSION")));
        assert!(
            l[1].starts_with("nsrm farm run: 12 frame(s) in this shard, of 48 in the batch; device asked: --device gpu, --adapter \"RTX\\n\", --jobs 4"),
            "{}",
            l[1]
        );
        assert!(!host_name().is_empty());
    }
}
