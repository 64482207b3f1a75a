//! `nsrm studio`: the security gate (token, Host, Origin: 403), the API against the CLI (the
//! same reading, model file, statistics and exported bytes), hostile uploads (a clear message,
//! the server still up), nothing written outside the per-run temporary directory, and the
//! browser test (tests/browser/studio.test.mjs in headless Chromium).

use crate::common::{nsrm, tempdir};
use serde_json::Value;
use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// A running `nsrm studio --no-browser`, stopped (SIGTERM, then kill) when dropped.
pub struct Server {
    child: Child,
    pub port: u16,
    pub token: String,
    pub tmp: PathBuf,
}

impl Server {
    /// Starts the studio in `cwd` with `args` and waits (bounded) for its URL.
    pub fn start(cwd: &Path, args: &[&str]) -> Server {
        let mut child = nsrm()
            .current_dir(cwd)
            .arg("studio")
            .arg("--no-browser")
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("starting nsrm studio");
        let stdout = child.stdout.take().unwrap();
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines() {
                let Ok(line) = line else { break };
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        let first = rx.recv_timeout(Duration::from_secs(30));
        let second = rx.recv_timeout(Duration::from_secs(5));
        let (Ok(first), Ok(second)) = (first, second) else {
            let _ = child.kill();
            let _ = child.wait();
            panic!("nsrm studio printed no URL within 30 s");
        };
        let url = first
            .strip_prefix("nsrm studio: ")
            .expect("the URL line")
            .to_string();
        let rest = url
            .strip_prefix("http://127.0.0.1:")
            .expect("served on 127.0.0.1");
        let (port, token) = rest.split_once("/?token=").expect("a token in the URL");
        let tmp = second
            .split("temporary files in ")
            .nth(1)
            .and_then(|s| s.split(';').next())
            .expect("the temporary directory")
            .to_string();
        Server {
            child,
            port: port.parse().unwrap(),
            token: token.to_string(),
            tmp: PathBuf::from(tmp),
        }
    }

    /// One request; `headers` replace the defaults (Host of 127.0.0.1, the token header).
    pub fn raw(
        &self,
        method: &str,
        path: &str,
        headers: &[(&str, &str)],
        body: &[u8],
    ) -> (u16, Vec<(String, String)>, Vec<u8>) {
        let mut s = TcpStream::connect(("127.0.0.1", self.port)).expect("connecting");
        s.set_read_timeout(Some(Duration::from_secs(300))).unwrap();
        // HTTP/1.0: the whole body, never chunked, then the connection closes.
        let mut req = format!("{method} {path} HTTP/1.0\r\nConnection: close\r\n");
        for (k, v) in headers {
            req.push_str(&format!("{k}: {v}\r\n"));
        }
        req.push_str(&format!("Content-Length: {}\r\n\r\n", body.len()));
        s.write_all(req.as_bytes()).unwrap();
        // The server may answer (and close) before reading a refused body.
        let _ = s.write_all(body);
        let mut buf = Vec::new();
        let _ = s.read_to_end(&mut buf);
        let at = buf
            .windows(4)
            .position(|w| w == b"\r\n\r\n")
            .unwrap_or_else(|| panic!("no HTTP header in {:?}", String::from_utf8_lossy(&buf)));
        let head = String::from_utf8_lossy(&buf[..at]).into_owned();
        let mut lines = head.lines();
        let status: u16 = lines
            .next()
            .and_then(|l| l.split_whitespace().nth(1))
            .and_then(|c| c.parse().ok())
            .expect("a status line");
        let hs = lines
            .filter_map(|l| l.split_once(':'))
            .map(|(k, v)| (k.trim().to_ascii_lowercase(), v.trim().to_string()))
            .collect();
        (status, hs, buf[at + 4..].to_vec())
    }

    /// A request as the page makes it (Host 127.0.0.1:PORT, the token header).
    pub fn call(&self, method: &str, path: &str, body: &[u8]) -> (u16, Vec<u8>) {
        let host = format!("127.0.0.1:{}", self.port);
        let (st, _, b) = self.raw(
            method,
            path,
            &[("Host", &host), ("X-Nsrm-Token", &self.token)],
            body,
        );
        (st, b)
    }

    /// A JSON request that must succeed.
    pub fn json(&self, method: &str, path: &str, body: &str) -> Value {
        let (st, b) = self.call(method, path, body.as_bytes());
        let text = String::from_utf8_lossy(&b);
        assert_eq!(st, 200, "{method} {path}: {text}");
        serde_json::from_slice(&b).unwrap_or_else(|e| panic!("{method} {path}: {e}: {text}"))
    }

    /// SIGTERM, and the exit status within 10 s.
    pub fn stop(&mut self) -> Option<std::process::ExitStatus> {
        let _ = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status();
        let t0 = Instant::now();
        while t0.elapsed() < Duration::from_secs(10) {
            if let Ok(Some(st)) = self.child.try_wait() {
                return Some(st);
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
        None
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        if let Ok(None) = self.child.try_wait() {
            self.stop();
        }
    }
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A synthetic CC24 scene (`render-scene`) in `dir`.
pub fn scene(dir: &Path, name: &str) -> PathBuf {
    crate::common::cc24_scene(dir, name, &[])
}

fn cli(dir: &Path, args: &[&str]) -> Vec<u8> {
    let out = nsrm().current_dir(dir).args(args).output().unwrap();
    assert!(
        out.status.success(),
        "nsrm {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out.stdout
}

#[test]
fn requests_without_the_token_or_from_another_host_or_origin_are_refused() {
    let d = tempdir("studio-gate");
    let srv = Server::start(&d, &[]);
    let host = format!("127.0.0.1:{}", srv.port);
    let ok_q = format!("/api/info?token={}", srv.token);
    let with = |h: &[(&str, &str)], path: &str| srv.raw("GET", path, h, b"").0;
    // The page and the API with the token (query or header) and a local Host.
    assert_eq!(with(&[("Host", &host)], &ok_q), 200);
    assert_eq!(
        with(&[("Host", &format!("localhost:{}", srv.port))], &ok_q),
        200
    );
    assert_eq!(
        with(&[("Host", &host)], &format!("/?token={}", srv.token)),
        200
    );
    // No token, a wrong one, one of another length.
    assert_eq!(with(&[("Host", &host)], "/api/info"), 403);
    assert_eq!(with(&[("Host", &host)], "/"), 403);
    let wrong: String = srv
        .token
        .chars()
        .map(|c| if c == '0' { '1' } else { '0' })
        .collect();
    assert_eq!(
        with(&[("Host", &host)], &format!("/api/info?token={wrong}")),
        403
    );
    assert_eq!(
        with(&[("Host", &host), ("X-Nsrm-Token", "x")], "/api/info"),
        403
    );
    // DNS rebinding: a foreign Host, even with the token; another port; no Host.
    assert_eq!(with(&[("Host", "evil.example")], &ok_q), 403);
    assert_eq!(
        with(&[("Host", &format!("evil.example:{}", srv.port))], &ok_q),
        403
    );
    assert_eq!(
        with(&[("Host", &format!("127.0.0.1:{}", srv.port ^ 1))], &ok_q),
        403
    );
    assert_eq!(with(&[], &ok_q), 403);
    // Cross-site requests: a foreign Origin or Sec-Fetch-Site: cross-site.
    assert_eq!(
        with(&[("Host", &host), ("Origin", "http://evil.example")], &ok_q),
        403
    );
    assert_eq!(with(&[("Host", &host), ("Origin", "null")], &ok_q), 403);
    assert_eq!(
        with(
            &[("Host", &host), ("Origin", &format!("https://{host}"))],
            &ok_q
        ),
        403
    );
    assert_eq!(
        with(&[("Host", &host), ("Sec-Fetch-Site", "cross-site")], &ok_q),
        403
    );
    assert_eq!(
        with(
            &[("Host", &host), ("Origin", &format!("http://{host}"))],
            &ok_q
        ),
        200
    );
    // A state-changing request without the token does nothing.
    let (st, _, _) = srv.raw("POST", "/api/frames?name=x.exr", &[("Host", &host)], b"abc");
    assert_eq!(st, 403);
    // Two runs have different tokens.
    let srv2 = Server::start(&d, &[]);
    assert_ne!(srv.token, srv2.token);
    assert!(srv.token.len() >= 32);
}

/// The page's reading, fit, comparison and export equal the CLI's; the command line it shows
/// reproduces the model file and the export byte for byte.
#[test]
fn the_api_gives_the_cli_numbers_and_bytes() {
    let d = tempdir("studio-api");
    let frame = scene(&d, "scene.exr");
    let work = d.join("work");
    std::fs::create_dir_all(&work).unwrap();
    let srv = Server::start(&work, &[s(&frame)]);

    // The listed frame, read as `chart extract --json` reads it.
    let st = srv.json("POST", "/api/files/0/open", "");
    let id = st["id"].as_str().unwrap().to_string();
    assert!(st["error"].is_null(), "{}", st["error"]);
    cli(
        &d,
        &[
            "chart",
            "extract",
            "scene.exr",
            "--chart",
            "cc24",
            "-o",
            "p.csv",
            "--json",
            "r.json",
        ],
    );
    let cli_reading: Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("r.json")).unwrap()).unwrap();
    let reading = &st["reading"];
    assert_eq!(reading["patches"], cli_reading["patches"]);
    assert_eq!(reading["corners"], cli_reading["corners"]);
    assert_eq!(reading["provenance"], cli_reading["provenance"]);

    // Moved corners: a new reading, equal to `--corners`.
    let mut corners: Vec<[f64; 2]> = serde_json::from_value(reading["corners"].clone()).unwrap();
    corners[2][0] += 3.0;
    corners[2][1] -= 2.0;
    let body = serde_json::json!({"chart": "cc24", "corners": corners}).to_string();
    let st2 = srv.json("POST", &format!("/api/frames/{id}/reading"), &body);
    assert_ne!(st2["reading"]["patches"], reading["patches"]);
    let spec = corners
        .iter()
        .map(|p| format!("{},{}", p[0], p[1]))
        .collect::<Vec<_>>()
        .join(" ");
    cli(
        &d,
        &[
            "chart",
            "extract",
            "scene.exr",
            "--chart",
            "cc24",
            "--corners",
            &spec,
            "-o",
            "p2.csv",
            "--json",
            "r2.json",
        ],
    );
    let cli2: Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("r2.json")).unwrap()).unwrap();
    assert_eq!(st2["reading"]["patches"], cli2["patches"]);

    // Exclude a patch by hand, fit, export; then run the page's command lines in a fresh
    // directory holding the frame: the same model file and CLF, byte for byte.
    let label = st2["reading"]["patches"][5]["label"].as_str().unwrap();
    let body =
        serde_json::json!({"chart": "cc24", "corners": corners, "exclude": [label]}).to_string();
    let st3 = srv.json("POST", &format!("/api/frames/{id}/reading"), &body);
    assert!(st3["patches_spec"].as_str().unwrap().len() > 10);
    let fit = srv.json(
        "POST",
        &format!("/api/frames/{id}/fit"),
        r#"{"kind": "nsrm", "order": 3, "objective": "de00", "preserve_white": false}"#,
    );
    let n = fit["n_patches"].as_u64().unwrap();
    assert_eq!(fit["patches"].as_array().unwrap().len() as u64, n);
    assert!(fit["patches"]
        .as_array()
        .unwrap()
        .iter()
        .all(|p| p["label"] != label));
    let (code, model_bytes) = srv.call("GET", &format!("/api/frames/{id}/model.json"), b"");
    assert_eq!(code, 200);
    let (code, clf) = srv.call(
        "GET",
        &format!("/api/frames/{id}/export?format=clf&space=acescg"),
        b"",
    );
    assert_eq!(code, 200, "{}", String::from_utf8_lossy(&clf));
    let (code, command) = srv.call(
        "GET",
        &format!("/api/frames/{id}/command?format=clf&space=acescg"),
        b"",
    );
    assert_eq!(code, 200);
    let command = String::from_utf8(command).unwrap();
    assert!(command.contains("--patches"), "{command}");
    assert!(command.contains("--objective de00"), "{command}");
    let rerun = d.join("rerun");
    std::fs::create_dir_all(&rerun).unwrap();
    let nsrm_bin = env!("CARGO_BIN_EXE_nsrm");
    for line in command.lines() {
        let line = line.replacen("nsrm ", &format!("'{nsrm_bin}' "), 1);
        let out = Command::new("sh")
            .arg("-c")
            .arg(&line)
            .current_dir(&rerun)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{line}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    assert_eq!(
        std::fs::read(rerun.join("model.json")).unwrap(),
        model_bytes
    );
    assert_eq!(std::fs::read(rerun.join("model.clf")).unwrap(), clf);
    assert_eq!(
        srv.call("GET", &format!("/api/frames/{id}/patches.csv"), b"")
            .1,
        std::fs::read(rerun.join("patches.csv")).unwrap()
    );

    // Every model side by side: the numbers `eval --capture … --json` prints, running the
    // command lines the page shows (one per kind, the orders that could be fitted).
    let cmp = srv.json(
        "POST",
        &format!("/api/frames/{id}/compare"),
        r#"{"objective": "ls"}"#,
    );
    for (key, extra) in [("leave_one_out", ""), ("in_sample", " --in-sample")] {
        let ours: Vec<&Value> = cmp[key]
            .as_array()
            .unwrap()
            .iter()
            .filter(|r| r["error"].is_null())
            .collect();
        let mut theirs: Vec<Value> = Vec::new();
        for line in cmp["command"].as_str().unwrap().lines() {
            let line = line.replacen("nsrm ", &format!("'{nsrm_bin}' "), 1);
            let out = Command::new("sh")
                .arg("-c")
                .arg(format!("{line}{extra}"))
                .current_dir(&rerun)
                .output()
                .unwrap();
            assert!(
                out.status.success(),
                "{line}: {}",
                String::from_utf8_lossy(&out.stderr)
            );
            let v: Value = serde_json::from_slice(&out.stdout).unwrap();
            theirs.extend(v["results"].as_array().unwrap().iter().cloned());
        }
        assert!(ours.len() >= 10, "{key}: {}", ours.len());
        assert_eq!(ours.len(), theirs.len(), "{key}");
        for (a, b) in ours.iter().zip(&theirs) {
            for k in [
                "model",
                "order",
                "mean",
                "median",
                "p95",
                "max",
                "per_patch",
            ] {
                assert_eq!(a[k], b[k], "{key} {k} of {} {}", a["model"], a["order"]);
            }
        }
    }
    assert!(cmp["best"]["mean"].as_f64().unwrap() > 0.0);

    // Previews: PNGs; the corrected one needs the fit and says where it ran.
    for path in ["preview.png", "overlay.png", "corrected.png?space=acescg"] {
        let (code, hs, body) = srv.raw(
            "GET",
            &format!("/api/frames/{id}/{path}"),
            &[
                ("Host", &format!("127.0.0.1:{}", srv.port)),
                ("X-Nsrm-Token", &srv.token),
            ],
            b"",
        );
        assert_eq!(code, 200, "{path}");
        assert!(body.starts_with(b"\x89PNG"), "{path}");
        if path.starts_with("corrected") {
            assert!(hs.iter().any(|(k, v)| k == "x-nsrm-device" && v == "cpu"));
        }
    }
    let sh = srv.json("GET", &format!("/api/frames/{id}/shader?space=acescg"), "");
    assert!(sh["wgsl"].as_str().unwrap().contains("@compute"));

    // Nothing was written in the working directory.
    assert_eq!(std::fs::read_dir(&work).unwrap().count(), 0);
}

#[test]
fn uploads_hostile_input_and_cleanup() {
    let d = tempdir("studio-upload");
    let frame = scene(&d, "up.exr");
    let bytes = std::fs::read(&frame).unwrap();
    let work = d.join("work");
    std::fs::create_dir_all(&work).unwrap();
    let mut srv = Server::start(&work, &["--max-pixels", "600000"]);
    let tmp = srv.tmp.clone();
    assert!(tmp.is_dir());

    // The file's bytes as the body, under a hostile name: kept inside the temporary directory.
    let (code, b) = srv.call("POST", "/api/frames?name=..%2F..%2Fup.exr", &bytes);
    assert_eq!(code, 200, "{}", String::from_utf8_lossy(&b));
    let st: Value = serde_json::from_slice(&b).unwrap();
    assert_eq!(st["name"], "up.exr");
    let read_at = st["reading"]["frame"].as_str().unwrap();
    assert!(Path::new(read_at).starts_with(&tmp), "{read_at}");
    // Multipart field `file`.
    let mut mp = b"--B0undary\r\nContent-Disposition: form-data; name=\"note\"\r\n\r\nx\r\n--B0undary\r\nContent-Disposition: form-data; name=\"file\"; filename=\"m.exr\"\r\nContent-Type: image/x-exr\r\n\r\n".to_vec();
    mp.extend_from_slice(&bytes);
    mp.extend_from_slice(b"\r\n--B0undary--\r\n");
    let host = format!("127.0.0.1:{}", srv.port);
    let (code, _, b) = srv.raw(
        "POST",
        "/api/frames",
        &[
            ("Host", &host),
            ("X-Nsrm-Token", &srv.token),
            ("Content-Type", "multipart/form-data; boundary=B0undary"),
        ],
        &mp,
    );
    assert_eq!(code, 200, "{}", String::from_utf8_lossy(&b));
    let st2: Value = serde_json::from_slice(&b).unwrap();
    assert_eq!(st2["reading"]["patches"], st["reading"]["patches"]);

    // Hostile uploads: a clear message, and the server keeps serving.
    let mut truncated = bytes.clone();
    truncated.truncate(bytes.len() / 2);
    let mut flipped = bytes.clone();
    for i in (400..flipped.len()).step_by(97) {
        flipped[i] ^= 0x5a;
    }
    let cases: Vec<(&str, Vec<u8>)> = vec![
        ("garbage.exr", b"not an image at all".to_vec()),
        ("empty.exr", Vec::new()),
        ("half.exr", truncated),
        ("flipped.exr", flipped),
        ("zeros.tif", vec![0u8; 5000]),
    ];
    for (name, body) in cases {
        let (code, b) = srv.call("POST", &format!("/api/frames?name={name}"), &body);
        let text = String::from_utf8_lossy(&b);
        if code == 200 {
            // A damaged frame may still decode (to other pixels); then it is just read.
            continue;
        }
        assert!((400..500).contains(&code), "{name}: {code} {text}");
        let v: Value = serde_json::from_str(&text).unwrap_or_else(|_| panic!("{name}: {text}"));
        assert!(v["error"].as_str().unwrap().len() > 10, "{name}: {text}");
        assert_eq!(srv.call("GET", "/api/info", b"").0, 200, "after {name}");
    }
    // Over the size bound of the frame limit (600000 pixels × 16 bytes + 1 MiB).
    let big = vec![0u8; 600_000 * 16 + (1 << 20) + 70_000];
    let (code, b) = srv.call("POST", "/api/frames?name=big.exr", &big);
    assert_eq!(code, 413, "{}", String::from_utf8_lossy(&b));
    // Bad JSON, unknown fields, out-of-range values, unknown endpoints and frames.
    let id = st["id"].as_str().unwrap();
    for (path, body, want) in [
        (format!("/api/frames/{id}/fit"), "{", 400),
        (format!("/api/frames/{id}/fit"), r#"{"kind": "xyz"}"#, 400),
        (format!("/api/frames/{id}/fit"), r#"{"order": 9}"#, 400),
        (format!("/api/frames/{id}/fit"), r#"{"colour": 1}"#, 400),
        (
            format!("/api/frames/{id}/reading"),
            r#"{"flat": "/etc/passwd"}"#,
            400,
        ),
        ("/api/frames/f999/fit".to_string(), "{}", 404),
        ("/api/nothing".to_string(), "{}", 404),
    ] {
        let (code, b) = srv.call("POST", &path, body.as_bytes());
        assert_eq!(code, want, "{path} {body}: {}", String::from_utf8_lossy(&b));
    }
    // A bad name (of the library's typed options) is refused naming the names allowed.
    for (path, body, allowed) in [
        ("fit", r#"{"kind": "xyz"}"#, "lrm, prm, rprm or nsrm"),
        ("fit", r#"{"normalise": "x"}"#, "raw or white-balanced"),
        (
            "fit",
            r#"{"ridge": "x"}"#,
            "auto (GCV), auto-loo or a number",
        ),
        ("compare", r#"{"objective": "x"}"#, "ls, de00 or de00:P"),
        ("reading", r#"{"chart": "x"}"#, "cc24, sg, spyder24"),
        ("reading", r#"{"flat": "x"}"#, "none, neutrals, file:N"),
    ] {
        let path = format!("/api/frames/{id}/{path}");
        let (code, b) = srv.call("POST", &path, body.as_bytes());
        let text = String::from_utf8_lossy(&b);
        assert_eq!(code, 400, "{path} {body}: {text}");
        assert!(text.contains(allowed), "{path} {body}: {text}");
    }
    // Corners that make no chart: the reading fails with the reason, shown in the page.
    let st = srv.json(
        "POST",
        &format!("/api/frames/{id}/reading"),
        r#"{"chart": "cc24", "corners": [[0,0],[0,0],[0,0],[0,0]]}"#,
    );
    assert!(st["reading"].is_null());
    assert!(
        st["error"].as_str().unwrap().contains("convex"),
        "{}",
        st["error"]
    );
    let (code, _) = srv.call("GET", &format!("/api/frames/{id}/export?format=clf"), b"");
    assert_eq!(code, 400, "an export before a fit");
    assert_eq!(srv.call("GET", "/api/info", b"").0, 200);

    // Closing a frame removes its upload; it is then gone from the API.
    let id2 = st2["id"].as_str().unwrap();
    assert_eq!(
        srv.json("GET", &format!("/api/frames/{id2}"), "")["id"],
        id2
    );
    let upload_dir = tmp.join(id2);
    assert!(upload_dir.join("m.exr").is_file());
    srv.json("DELETE", &format!("/api/frames/{id2}"), "");
    assert!(!upload_dir.exists());
    assert_eq!(srv.call("GET", &format!("/api/frames/{id2}"), b"").0, 404);

    // SIGTERM: the temporary directory goes, nothing was written in the working directory.
    let status = srv.stop().expect("stopped within 10 s");
    assert!(!status.success());
    assert!(!tmp.exists(), "{} left behind", tmp.display());
    assert_eq!(std::fs::read_dir(&work).unwrap().count(), 0);
}

/// The page in headless Chromium (tests/browser/studio.test.mjs, puppeteer-core): load, drop a
/// `render-scene` frame, see the overlay, drag a corner, fit, download a CLF equal to `nsrm
/// export`'s, no console errors; screenshots in target/studio-browser/.
#[test]
fn the_page_in_a_real_browser() {
    let root = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."));
    let Some(chromium) = crate::common::browser_prerequisites() else {
        return;
    };
    let out_dir = root.join("target/studio-browser");
    let _ = std::fs::remove_dir_all(&out_dir);
    std::fs::create_dir_all(&out_dir).unwrap();
    let work = tempdir("studio-browser-work");
    crate::common::run_browser_script(
        "studio.test.mjs",
        "studio-browser",
        &chromium,
        &[
            ("NSRM_BIN", Path::new(env!("CARGO_BIN_EXE_nsrm"))),
            ("STUDIO_OUT", &out_dir),
            ("STUDIO_WORK", &work),
        ],
    );
    assert!(
        !root.join("dconf").exists(),
        "the browser left a dconf directory in the repository"
    );
}

/// The corrected preview, computed by the server on the GPU (`--device gpu`: lavapipe here) and
/// on the CPU (`--device cpu`), says where it ran and differs by at most one 8-bit code.
#[test]
fn the_server_preview_on_the_gpu_equals_the_cpu() {
    let d = tempdir("studio-gpu");
    let frame = scene(&d, "scene.exr");
    let mut previews = Vec::new();
    for device in ["gpu", "cpu"] {
        let srv = Server::start(&d, &["--device", device, s(&frame)]);
        let st = srv.json("POST", "/api/files/0/open", "");
        let id = st["id"].as_str().unwrap().to_string();
        assert!(st["error"].is_null(), "{}", st["error"]);
        srv.json(
            "POST",
            &format!("/api/frames/{id}/fit"),
            r#"{"kind": "nsrm", "order": 3}"#,
        );
        let host = format!("127.0.0.1:{}", srv.port);
        let (status, headers, body) = srv.raw(
            "GET",
            &format!("/api/frames/{id}/corrected.png?space=acescg"),
            &[("Host", &host), ("X-Nsrm-Token", &srv.token)],
            b"",
        );
        let text = String::from_utf8_lossy(&body).into_owned();
        if device == "gpu" && status != 200 && text.contains("the server's GPU") {
            crate::common::skip(&format!("no GPU adapter for the studio: {text}"));
            return;
        }
        assert_eq!(status, 200, "{device}: {text}");
        let header = |k: &str| {
            headers
                .iter()
                .find(|(n, _)| n == k)
                .map(|(_, v)| v.clone())
                .unwrap_or_default()
        };
        assert_eq!(header("x-nsrm-device"), device, "{headers:?}");
        assert!(!header("x-nsrm-device-detail").is_empty(), "{headers:?}");
        let img = image::load_from_memory(&body).unwrap().to_rgb8();
        previews.push(img);
    }
    let (g, c) = (&previews[0], &previews[1]);
    assert_eq!(g.dimensions(), c.dimensions());
    let max = g
        .as_raw()
        .iter()
        .zip(c.as_raw())
        .map(|(a, b)| a.abs_diff(*b))
        .max()
        .unwrap();
    assert!(max <= 1, "GPU and CPU previews differ by {max}/255");
    // Not a blank image: the comparison means something.
    let distinct: std::collections::BTreeSet<_> = c.pixels().map(|p| p.0).collect();
    assert!(distinct.len() > 100, "{} colours", distinct.len());
}

/// Runs the page's command lines (`GET …/command`) in `dir` with the frame there as `name`.
fn rerun(dir: &Path, frame: &Path, name: &str, command: &str) {
    std::fs::create_dir_all(dir).unwrap();
    std::os::unix::fs::symlink(frame, dir.join(name)).unwrap();
    let nsrm_bin = env!("CARGO_BIN_EXE_nsrm");
    for line in command.lines() {
        let line = line.replacen("nsrm ", &format!("'{nsrm_bin}' "), 1);
        let out = Command::new("sh")
            .arg("-c")
            .arg(&line)
            .current_dir(dir)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{line}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
}

/// Upload → reading → fit → every profile format the studio offers (DCP, and ICC where the
/// library writes it), each equal byte for byte to the CLI's run of the page's command lines.
fn frame_to_profiles(d: &Path, srv: &Server, frame: &Path, name: &str, chart: &str) {
    let bytes = std::fs::read(frame).unwrap();
    let (code, body) = srv.call("POST", &format!("/api/frames?name={name}"), &bytes);
    assert_eq!(code, 200, "{name}: {}", String::from_utf8_lossy(&body));
    let st: Value = serde_json::from_slice(&body).unwrap();
    let id = st["id"].as_str().unwrap().to_string();
    let st = if st["settings"]["chart"] != chart {
        srv.json(
            "POST",
            &format!("/api/frames/{id}/reading"),
            &format!(r#"{{"chart": "{chart}"}}"#),
        )
    } else {
        st
    };
    assert!(st["error"].is_null(), "{name}: {}", st["error"]);
    let fit = srv.json(
        "POST",
        &format!("/api/frames/{id}/fit"),
        r#"{"kind": "rprm", "order": 2}"#,
    );
    assert!(fit["in_sample"]["mean"].as_f64().unwrap() < 5.0, "{fit}");
    let info = srv.json("GET", "/api/info", "");
    let formats: Vec<String> = info["formats"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f.as_str().unwrap().to_string())
        .filter(|f| f == "dcp" || f == "icc")
        .collect();
    assert!(formats.iter().any(|f| f == "dcp"), "{formats:?}");
    for fmt in formats {
        let (code, file) = srv.call(
            "GET",
            &format!("/api/frames/{id}/export?format={fmt}&space=xyz"),
            b"",
        );
        assert_eq!(code, 200, "{fmt}: {}", String::from_utf8_lossy(&file));
        let (_, command) = srv.call(
            "GET",
            &format!("/api/frames/{id}/command?format={fmt}&space=xyz"),
            b"",
        );
        let command = String::from_utf8(command).unwrap();
        let dir = d.join(format!("rerun-{chart}-{fmt}"));
        rerun(&dir, frame, name, &command);
        let mut theirs = std::fs::read(dir.join(format!("model.{fmt}"))).unwrap();
        let mut ours = file;
        if fmt == "icc" {
            // The ICC header's creation date and time (bytes 24..36) is the moment of writing.
            for b in [&mut ours, &mut theirs] {
                if b.len() >= 36 {
                    b[24..36].fill(0);
                }
            }
        }
        assert!(
            ours == theirs,
            "{name}: the {fmt} differs from the CLI's ({} vs {} bytes)",
            ours.len(),
            theirs.len()
        );
    }
}

/// A person goes from a raw frame of a chart (`../shared/data/colorchart.dng`) and from an SG
/// scene to exported profiles through the API alone.
#[test]
fn raw_and_sg_frames_to_exported_profiles_through_the_api() {
    let d = tempdir("studio-profiles");
    let work = d.join("work");
    std::fs::create_dir_all(&work).unwrap();
    let srv = Server::start(&work, &[]);
    if let Some(sg) = crate::common::sg_path() {
        let f = d.join("sg.exr");
        cli(
            &d,
            &[
                "render-scene",
                "--chart",
                "sg",
                "--reflectances",
                s(&sg),
                "--width",
                "1000",
                "--height",
                "700",
                "--seed",
                "3",
                "--min-area",
                "0.25",
                "-o",
                s(&f),
            ],
        );
        frame_to_profiles(&d, &srv, &f, "sg.exr", "sg");
    }
    let dng = PathBuf::from(concat!(
        concat!(env!("CARGO_MANIFEST_DIR"), "/../.."),
        "/../shared/data/colorchart.dng"
    ));
    if !dng.exists() {
        crate::common::skip(&format!("{} is absent", dng.display()));
        return;
    }
    frame_to_profiles(&d, &srv, &dng, "colorchart.dng", "cc24");
    // Nothing was written in the working directory.
    assert_eq!(std::fs::read_dir(&work).unwrap().count(), 0);
}

/// A flat frame uploaded for an open frame is used as `--flat` uses it: the reading equals
/// `chart extract --flat`, the command line names it; a hostile flat is refused clearly, a flat
/// of another size is explained without naming a CLI flag.
#[test]
fn an_uploaded_flat_frame_is_the_flat_field() {
    let d = tempdir("studio-flat");
    let frame = crate::common::cc24_scene(
        &d,
        "scene.exr",
        &["--gradient", "0.3", "--flat-output", "flat.exr"],
    );
    let work = d.join("work");
    std::fs::create_dir_all(&work).unwrap();
    let srv = Server::start(&work, &[s(&frame)]);
    let st = srv.json("POST", "/api/files/0/open", "");
    let id = st["id"].as_str().unwrap().to_string();
    assert!(st["error"].is_null(), "{}", st["error"]);
    let flat = std::fs::read(d.join("flat.exr")).unwrap();
    let (code, body) = srv.call(
        "POST",
        &format!("/api/frames/{id}/flat?name=flat.exr"),
        &flat,
    );
    assert_eq!(code, 200, "{}", String::from_utf8_lossy(&body));
    let st: Value = serde_json::from_slice(&body).unwrap();
    assert!(st["error"].is_null(), "{}", st["error"]);
    assert_eq!(st["flat_upload"], "flat.exr");
    assert_eq!(st["settings"]["flat"], "upload");
    assert_eq!(st["reading"]["provenance"]["flat"], "flat frame");
    cli(
        &d,
        &[
            "chart",
            "extract",
            "scene.exr",
            "--chart",
            "cc24",
            "--flat",
            "flat.exr",
            "-o",
            "p.csv",
            "--json",
            "r.json",
        ],
    );
    let theirs: Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("r.json")).unwrap()).unwrap();
    assert_eq!(st["reading"]["patches"], theirs["patches"]);
    assert_eq!(
        st["reading"]["provenance"]["light_nonuniformity"],
        theirs["provenance"]["light_nonuniformity"]
    );
    assert!(
        st["command"].as_str().unwrap().contains("--flat flat.exr"),
        "{}",
        st["command"]
    );
    // Back to none and again to the upload: no new upload needed.
    let none = srv.json(
        "POST",
        &format!("/api/frames/{id}/reading"),
        r#"{"chart": "cc24", "flat": "none"}"#,
    );
    assert_ne!(none["reading"]["patches"], theirs["patches"]);
    let again = srv.json(
        "POST",
        &format!("/api/frames/{id}/reading"),
        r#"{"chart": "cc24", "flat": "upload"}"#,
    );
    assert_eq!(again["reading"]["patches"], theirs["patches"]);
    // A hostile flat: a clear 400, the server still serving.
    let (code, body) = srv.call(
        "POST",
        &format!("/api/frames/{id}/flat?name=x.exr"),
        b"v/1\x01not an exr at all",
    );
    let text = String::from_utf8_lossy(&body);
    assert_eq!(code, 400, "{text}");
    assert!(text.contains("not a flat frame nsrm can read"), "{text}");
    // A flat of another size: the reading explains it in the page's words.
    let small = d.join("small.exr");
    cli(
        &d,
        &[
            "render-scene",
            "--chart",
            "cc24",
            "--width",
            "400",
            "--height",
            "300",
            "-o",
            s(&small),
        ],
    );
    let (code, body) = srv.call(
        "POST",
        &format!("/api/frames/{id}/flat?name=small.exr"),
        &std::fs::read(&small).unwrap(),
    );
    assert_eq!(code, 200, "{}", String::from_utf8_lossy(&body));
    let st: Value = serde_json::from_slice(&body).unwrap();
    let err = st["error"].as_str().unwrap_or_default();
    assert!(err.contains("flat frame is 400×300"), "{err}");
    assert!(
        !err.contains("--"),
        "the page's message names a CLI flag: {err}"
    );
    srv.json("GET", "/api/info", "");
}

/// A long comparison does not hold the frame: its state, a new reading and a preview are
/// answered while the models are still being evaluated.
#[test]
fn a_long_comparison_does_not_block_the_frame() {
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Arc;
    let d = tempdir("studio-compare");
    let frame = scene(&d, "scene.exr");
    let srv = Arc::new(Server::start(&d, &[s(&frame)]));
    let st = srv.json("POST", "/api/files/0/open", "");
    let id = st["id"].as_str().unwrap().to_string();
    assert!(st["error"].is_null(), "{}", st["error"]);
    let done = Arc::new(AtomicBool::new(false));
    let t0 = Instant::now();
    let worker = {
        let (srv, done, id) = (Arc::clone(&srv), Arc::clone(&done), id.clone());
        std::thread::spawn(move || {
            // Every kind × order, leave-one-out and in-sample, each fitted to ΔE00 (iterative):
            // long enough at any optimisation level for three requests to be answered first.
            let v = srv.json(
                "POST",
                &format!("/api/frames/{id}/compare"),
                r#"{"objective": "de00"}"#,
            );
            done.store(true, Ordering::SeqCst);
            v
        })
    };
    std::thread::sleep(Duration::from_millis(100));
    let mut answered = 0;
    for path in [
        format!("/api/frames/{id}"),
        format!("/api/frames/{id}/preview.png"),
        format!("/api/frames/{id}/overlay.png"),
    ] {
        let (code, _) = srv.call("GET", &path, b"");
        assert_eq!(code, 200, "{path}");
        if !done.load(Ordering::SeqCst) {
            answered += 1;
        }
    }
    let during = t0.elapsed();
    let cmp = worker.join().unwrap();
    let total = t0.elapsed();
    eprintln!("three requests answered {during:?} in; the comparison took {total:?}");
    assert!(cmp["best"]["mean"].as_f64().unwrap() > 0.0);
    assert_eq!(
        answered, 3,
        "requests waited for the comparison ({during:?} of {total:?})"
    );
}

/// Writes `bytes` on a new connection (write errors ignored: the server may close first) and
/// reads the answer for at most `wait`: its status, its body and how long it took.
fn exchange(port: u16, bytes: &[u8], wait: Duration) -> (Option<u16>, String, Duration) {
    let t0 = Instant::now();
    let mut s = TcpStream::connect(("127.0.0.1", port)).expect("connecting");
    s.set_read_timeout(Some(wait)).unwrap();
    s.set_write_timeout(Some(wait)).unwrap();
    let _ = s.write_all(bytes);
    let mut buf = Vec::new();
    let _ = s.read_to_end(&mut buf);
    let text = String::from_utf8_lossy(&buf).into_owned();
    let status = text
        .lines()
        .next()
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|c| c.parse().ok());
    let body = text.split_once("\r\n\r\n").map(|(_, b)| b.to_string());
    (status, body.unwrap_or_default(), t0.elapsed())
}

/// A refused request (no token, a body over its cap) is answered at once and its body never
/// read: a `Content-Length` of 10¹² or 2⁶⁴−1 neither aborts nor panics the server, stalled
/// clients (a head without its end, a body that never comes) hold no handler, and a stalled body
/// gets 408 within the idle bound.
#[test]
fn hostile_requests_are_bounded_before_they_are_read() {
    let d = tempdir("studio-bounds");
    let srv = Server::start(&d, &["--threads", "2"]);
    let host = format!("127.0.0.1:{}", srv.port);
    let tok = &srv.token;
    let quick = Duration::from_secs(5);
    for len in ["1000000000000", "18446744073709551615"] {
        // Without the token: 403 before any body byte is sent, more times than there are handlers.
        for _ in 0..5 {
            let req = format!(
                "POST /api/frames?name=x.exr HTTP/1.1\r\nHost: {host}\r\nContent-Length: {len}\r\n\r\n"
            );
            let (st, _, took) = exchange(srv.port, req.as_bytes(), Duration::from_secs(30));
            assert_eq!(st, Some(403), "Content-Length {len}");
            assert!(took < quick, "403 took {took:?}");
        }
        // With the token: 413 for an upload and for a JSON body, unread.
        for path in ["/api/frames?name=x.exr", "/api/frames/f1/reading"] {
            let req = format!(
                "POST {path} HTTP/1.1\r\nHost: {host}\r\nX-Nsrm-Token: {tok}\r\nContent-Length: {len}\r\n\r\n"
            );
            let (st, body, took) = exchange(srv.port, req.as_bytes(), Duration::from_secs(30));
            assert_eq!(st, Some(413), "{path} Content-Length {len}: {body}");
            assert!(took < quick, "413 took {took:?}");
        }
    }
    // A Content-Length past 2⁶⁴−1, a bad one, two that disagree: 4xx.
    for cl in [
        "Content-Length: 18446744073709551616",
        "Content-Length: -1",
        "Content-Length: 1e12",
        "Content-Length: 5\r\nContent-Length: 6",
    ] {
        let req = format!("POST /api/info HTTP/1.1\r\nHost: {host}\r\n{cl}\r\n\r\n");
        let (st, _, _) = exchange(srv.port, req.as_bytes(), Duration::from_secs(30));
        assert!(st.is_some_and(|s| (400..500).contains(&s)), "{cl}: {st:?}");
    }
    // Stalled clients, more than the handlers: heads never finished, bodies that never come
    // (with and without the token, on an upload and on a JSON endpoint).
    let mut stalled = Vec::new();
    for i in 0..8 {
        let mut s = TcpStream::connect(("127.0.0.1", srv.port)).unwrap();
        let head = match i % 4 {
            0 => format!("POST /api/frames HTTP/1.1\r\nHost: {host}\r\n"),
            1 => format!("POST /api/frames?name=a.exr HTTP/1.1\r\nHost: {host}\r\nX-Nsrm-Token: {tok}\r\nContent-Length: 100000\r\n\r\n"),
            2 => format!("POST /api/frames/f1/fit HTTP/1.1\r\nHost: {host}\r\nX-Nsrm-Token: {tok}\r\nContent-Length: 100000\r\n\r\n"),
            _ => format!("POST /api/frames HTTP/1.1\r\nHost: {host}\r\nContent-Length: 100000\r\n\r\n"),
        };
        s.write_all(head.as_bytes()).unwrap();
        stalled.push(s);
    }
    std::thread::sleep(Duration::from_millis(300));
    let t0 = Instant::now();
    assert_eq!(srv.call("GET", "/api/info", b"").0, 200);
    assert!(
        t0.elapsed() < Duration::from_secs(3),
        "the page waited {:?} behind stalled clients",
        t0.elapsed()
    );
    // A JSON body that stops half way: 408 within the idle bound (10 s), not never.
    let req = format!(
        "POST /api/frames/f1/fit HTTP/1.1\r\nHost: {host}\r\nX-Nsrm-Token: {tok}\r\nContent-Length: 100\r\n\r\n{{\"kind\""
    );
    let (st, _, took) = exchange(srv.port, req.as_bytes(), Duration::from_secs(60));
    assert_eq!(st, Some(408));
    assert!(took < Duration::from_secs(20), "408 after {took:?}");
    drop(stalled);
    assert_eq!(srv.call("GET", "/api/info", b"").0, 200);
}

/// `reference` and `reference_white` take built-in names only: a path is refused with the same
/// words whether or not the file exists, and nothing of the file comes back.
#[test]
fn a_reading_request_never_names_a_file() {
    let d = tempdir("studio-nopath");
    let frame = scene(&d, "scene.exr");
    let secret = d.join("secret.csv");
    std::fs::write(&secret, "SAMPLE_ID,X,Y,Z\nTOPSECRET,1,2,3\n").unwrap();
    let srv = Server::start(&d, &[s(&frame)]);
    let st = srv.json("POST", "/api/files/0/open", "");
    let id = st["id"].as_str().unwrap();
    let path = format!("/api/frames/{id}/reading");
    let missing = d.join("missing.csv");
    let mut answers = Vec::new();
    for field in ["reference", "reference_white"] {
        for p in [&secret, &missing] {
            let body = serde_json::json!({ field: p.to_str().unwrap() }).to_string();
            let (code, b) = srv.call("POST", &path, body.as_bytes());
            let text = String::from_utf8_lossy(&b).into_owned();
            assert_eq!(code, 400, "{field} {}: {text}", p.display());
            assert!(!text.contains("TOPSECRET"), "{text}");
            answers.push((field, text));
        }
    }
    assert_eq!(
        answers[0].1, answers[1].1,
        "reference: the answer tells a file exists"
    );
    assert_eq!(
        answers[2].1, answers[3].1,
        "white: the answer tells a file exists"
    );
    // The built-ins still work.
    let ok = srv.json(
        "POST",
        &path,
        r#"{"reference": "cc24-before2014", "reference_white": "D65"}"#,
    );
    assert!(ok["reading"].is_object(), "{ok}");
}

/// A chunked upload over the limit is answered 413 and leaves no partial file behind.
#[test]
fn a_refused_chunked_upload_leaves_no_file() {
    let d = tempdir("studio-chunked");
    let srv = Server::start(&d, &["--max-pixels", "1000"]);
    let host = format!("127.0.0.1:{}", srv.port);
    let limit = 1000 * 16 + (1 << 20);
    let mut req = format!(
        "POST /api/frames?name=big.exr HTTP/1.1\r\nHost: {host}\r\nX-Nsrm-Token: {}\r\nTransfer-Encoding: chunked\r\n\r\n",
        srv.token
    )
    .into_bytes();
    let chunk = vec![b'x'; 64 * 1024];
    for _ in 0..(2 * limit / chunk.len() + 1) {
        req.extend_from_slice(format!("{:x}\r\n", chunk.len()).as_bytes());
        req.extend_from_slice(&chunk);
        req.extend_from_slice(b"\r\n");
    }
    req.extend_from_slice(b"0\r\n\r\n");
    let (st, body, _) = exchange(srv.port, &req, Duration::from_secs(60));
    assert_eq!(st, Some(413), "{body}");
    let left: Vec<_> = walk(&srv.tmp);
    assert!(left.is_empty(), "left in the temporary folder: {left:?}");
    assert_eq!(srv.call("GET", "/api/info", b"").0, 200);
    // A chunked upload under the limit is read as the same bytes sent whole are.
    let srv2 = Server::start(&d, &[]);
    let bytes = std::fs::read(scene(&d, "small.exr")).unwrap();
    let mut req = format!(
        "POST /api/frames?name=small.exr HTTP/1.1\r\nHost: 127.0.0.1:{}\r\nX-Nsrm-Token: {}\r\nTransfer-Encoding: chunked\r\n\r\n",
        srv2.port, srv2.token
    )
    .into_bytes();
    for c in bytes.chunks(7919) {
        req.extend_from_slice(format!("{:X};ext=1\r\n", c.len()).as_bytes());
        req.extend_from_slice(c);
        req.extend_from_slice(b"\r\n");
    }
    req.extend_from_slice(b"0\r\nX-Trailer: 1\r\n\r\n");
    let (st, body, _) = exchange(srv2.port, &req, Duration::from_secs(120));
    assert_eq!(st, Some(200), "{body}");
    let chunked: Value = serde_json::from_str(&body).unwrap();
    let (code, b) = srv2.call("POST", "/api/frames?name=small.exr", &bytes);
    assert_eq!(code, 200);
    let whole: Value = serde_json::from_slice(&b).unwrap();
    assert_eq!(chunked["reading"]["patches"], whole["reading"]["patches"]);
    assert!(!chunked["reading"]["patches"].is_null());
}

fn walk(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).into_iter().flatten().flatten() {
        let p = e.path();
        if p.is_dir() {
            out.extend(walk(&p));
        } else {
            out.push(p);
        }
    }
    out
}

/// A reference file uploaded for a frame is its reference (the studio's `--reference FILE`):
/// the reading equals `chart extract --reference FILE`, the command line names the file by its
/// upload name, and an unreadable or oversized reference is refused without the server's path
/// and leaves no file behind.
#[test]
fn an_uploaded_reference_file_is_the_reference() {
    let d = tempdir("studio-reference");
    let frame = scene(&d, "scene.exr");
    let refs = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../assets"));
    let csv = d.join("my_chart.csv");
    std::fs::copy(refs.join("chart_cc24_before2014_d50.csv"), &csv).unwrap();
    let work = d.join("work");
    std::fs::create_dir_all(&work).unwrap();
    let srv = Server::start(&work, &[s(&frame)]);
    let st = srv.json("POST", "/api/files/0/open", "");
    let id = st["id"].as_str().unwrap().to_string();
    // The file holds Lab values (an X-Rite table): their white first, as --reference-white.
    srv.json(
        "POST",
        &format!("/api/frames/{id}/reading"),
        r#"{"chart": "cc24", "reference_white": "D50"}"#,
    );
    let (code, body) = srv.call(
        "POST",
        &format!("/api/frames/{id}/reference?name=my_chart.csv"),
        &std::fs::read(&csv).unwrap(),
    );
    assert_eq!(code, 200, "{}", String::from_utf8_lossy(&body));
    let st: Value = serde_json::from_slice(&body).unwrap();
    assert!(st["error"].is_null(), "{}", st["error"]);
    assert_eq!(st["reference_upload"], "my_chart.csv");
    assert_eq!(st["settings"]["reference"], "upload");
    let command = st["command"].as_str().unwrap();
    assert!(command.contains("--reference my_chart.csv"), "{command}");
    cli(
        &d,
        &[
            "chart",
            "extract",
            "scene.exr",
            "--chart",
            "cc24",
            "--reference",
            "my_chart.csv",
            "--reference-white",
            "D50",
            "-o",
            "p.csv",
            "--json",
            "r.json",
        ],
    );
    let theirs: Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("r.json")).unwrap()).unwrap();
    assert_eq!(st["reading"]["patches"], theirs["patches"]);
    // Back to the default and again to the upload: no new upload needed.
    let path = format!("/api/frames/{id}/reading");
    srv.json(
        "POST",
        &path,
        r#"{"chart": "cc24", "reference": null, "reference_white": "D50"}"#,
    );
    let again = srv.json(
        "POST",
        &path,
        r#"{"chart": "cc24", "reference": "upload", "reference_white": "D50"}"#,
    );
    assert_eq!(again["reading"]["patches"], theirs["patches"]);

    // Not a reference: a 400 naming the upload, not the server's copy.
    let (code, body) = srv.call(
        "POST",
        &format!("/api/frames/{id}/reference?name=bad.csv"),
        b"SAMPLE_ID,X,Y,Z\nnot a patch,1,2\n",
    );
    let text = String::from_utf8_lossy(&body).into_owned();
    assert_eq!(code, 400, "{text}");
    assert!(
        text.contains("bad.csv: not a reference nsrm can read"),
        "{text}"
    );
    assert!(!text.contains(&srv.tmp.display().to_string()), "{text}");
    // Over the limit: 413 before the body is read.
    let big = vec![b'1'; (1 << 20) + (128 << 10)];
    let (code, _) = srv.call(
        "POST",
        &format!("/api/frames/{id}/reference?name=big.csv"),
        &big,
    );
    assert_eq!(code, 413);
    let left: Vec<PathBuf> = walk(&srv.tmp)
        .into_iter()
        .filter(|p| {
            p.file_name()
                .is_some_and(|n| n == "bad.csv" || n == "big.csv")
        })
        .collect();
    assert!(left.is_empty(), "refused references left behind: {left:?}");
    // Another frame without an upload: `upload` is not a reference there.
    let other = srv.json("POST", "/api/files/0/open", "");
    let oid = other["id"].as_str().unwrap();
    let (code, body) = srv.call(
        "POST",
        &format!("/api/frames/{oid}/reading"),
        br#"{"chart": "cc24", "reference": "upload"}"#,
    );
    let text = String::from_utf8_lossy(&body);
    assert_eq!(code, 400, "{text}");
    assert!(text.contains("no reference file uploaded"), "{text}");
}
