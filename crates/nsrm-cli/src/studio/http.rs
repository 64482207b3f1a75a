//! The HTTP side: the security gate (token, Host, Origin), routing, bounded uploads (raw body or
//! multipart field `file`, streamed to disk) and replies. No handler can end the server: errors
//! become JSON `{"error": …}` replies and a panic becomes a 500.

use super::json;
use super::server::Request;
use super::session::Studio;
use super::wire::{Closed, ErrorBody};
use anyhow::{anyhow, bail, Context, Result};
use std::io::{Read, Write};
use std::path::Path;
use std::time::Duration;

const INDEX_HTML: &str = include_str!("web/index.html");
const APP_JS: &str = include_str!("web/app.js");
const STYLE_CSS: &str = include_str!("web/style.css");

/// Largest JSON request body (settings, fit options).
const MAX_JSON: u64 = 1 << 20;
/// The time a client has to send a JSON body (read before a handler slot is taken).
const JSON_DEADLINE: Duration = Duration::from_secs(30);
/// The time an upload may take: this, plus its byte limit at [`UPLOAD_RATE`] bytes a second.
const UPLOAD_BASE: Duration = Duration::from_secs(60);
const UPLOAD_RATE: u64 = 4 << 20;

/// What a handler answers.
pub(crate) struct Reply {
    pub(crate) status: u16,
    pub(crate) content_type: &'static str,
    pub(crate) body: Vec<u8>,
    /// A download: `Content-Disposition: attachment; filename=…`.
    pub(crate) filename: Option<String>,
    pub(crate) extra: Vec<(&'static str, String)>,
}

impl Reply {
    pub(crate) fn new(status: u16, content_type: &'static str, body: Vec<u8>) -> Reply {
        Reply {
            status,
            content_type,
            body,
            filename: None,
            extra: Vec::new(),
        }
    }

    pub(crate) fn download(content_type: &'static str, body: Vec<u8>, filename: String) -> Reply {
        Reply {
            filename: Some(filename),
            ..Reply::new(200, content_type, body)
        }
    }

    fn text(status: u16, msg: &str) -> Reply {
        Reply::new(status, "text/plain; charset=utf-8", msg.as_bytes().to_vec())
    }
}

/// An error that is the client's fault (400), with its message for the page.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub(crate) struct BadRequest(pub String);

/// A parsed request target.
pub(crate) struct Target {
    pub(crate) path: String,
    pub(crate) query: Vec<(String, String)>,
}

impl Target {
    pub(crate) fn param(&self, k: &str) -> Option<&str> {
        self.query
            .iter()
            .find(|(n, _)| n == k)
            .map(|(_, v)| v.as_str())
    }
}

fn parse_target(url: &str) -> Target {
    let (path, q) = url.split_once('?').unwrap_or((url, ""));
    let query = q
        .split('&')
        .filter(|s| !s.is_empty())
        .map(|kv| {
            let (k, v) = kv.split_once('=').unwrap_or((kv, ""));
            (percent_decode(k), percent_decode(v))
        })
        .collect();
    Target {
        path: percent_decode(path),
        query,
    }
}

/// `%XX` and `+` decoding (invalid escapes kept as they are; invalid UTF-8 replaced).
pub(crate) fn percent_decode(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        match b[i] {
            b'+' => out.push(b' '),
            b'%' if i + 2 < b.len()
                && b[i + 1].is_ascii_hexdigit()
                && b[i + 2].is_ascii_hexdigit() =>
            {
                let hex = |c: u8| (c as char).to_digit(16).unwrap_or(0) as u8;
                out.push(hex(b[i + 1]) * 16 + hex(b[i + 2]));
                i += 2;
            }
            c => out.push(c),
        }
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

fn header<'a>(req: &'a Request, name: &'static str) -> Option<&'a str> {
    req.header(name)
}

/// Equal in constant time (for the token).
fn same(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

/// Whether `host` (a `Host` header: `name[:port]`) is this server on loopback.
fn local_host(host: &str, port: u16) -> bool {
    let (name, p) = match host.rsplit_once(':') {
        Some((n, p)) if !n.ends_with(':') && !p.contains(']') => (n, Some(p)),
        _ => (host, None),
    };
    let name_ok = matches!(
        name.to_ascii_lowercase().as_str(),
        "127.0.0.1" | "localhost" | "[::1]"
    );
    name_ok && p.is_none_or(|p| p.parse::<u16>().ok() == Some(port))
}

/// The gate every request passes: `Err(reason)` means 403.
fn check(studio: &Studio, req: &Request, target: &Target) -> std::result::Result<(), String> {
    let host = header(req, "Host").ok_or("no Host header")?;
    if !local_host(host, studio.port) {
        return Err(format!("Host `{host}` is not this machine's loopback"));
    }
    if let Some(origin) = header(req, "Origin") {
        let rest = origin.strip_prefix("http://").unwrap_or("");
        if rest.is_empty() || !local_host(rest, studio.port) {
            return Err(format!("cross-origin request from `{origin}`"));
        }
    }
    if header(req, "Sec-Fetch-Site").is_some_and(|s| s.eq_ignore_ascii_case("cross-site")) {
        return Err("cross-site request".into());
    }
    let token = header(req, "X-Nsrm-Token").or_else(|| target.param("token"));
    match token {
        Some(t) if same(t.as_bytes(), studio.token.as_bytes()) => Ok(()),
        Some(_) => Err("wrong token".into()),
        None => Err("no token: open the URL that `nsrm studio` printed".into()),
    }
}

/// Answers one request (never panics out: a panic in a handler becomes a 500). A request the
/// gate refuses is answered without its body being read.
pub(crate) fn serve(studio: &Studio, mut req: Request) {
    let target = parse_target(req.url());
    let reply = match check(studio, &req, &target) {
        Err(why) => Reply::text(403, &format!("403 forbidden: {why}\n")),
        Ok(()) => {
            let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                handle(studio, &mut req, &target)
            }));
            match r {
                Ok(Ok(reply)) => reply,
                Ok(Err(e)) => {
                    let status = error_status(&e);
                    // In the page's words: no CLI flag named.
                    let msg = super::session::explain_for_page(e);
                    json(status, &ErrorBody { error: msg })
                }
                Err(_) => json(
                    500,
                    &ErrorBody {
                        error: "internal error (a bug in nsrm studio): the server is still running; please report it".into(),
                    },
                ),
            }
        }
    };
    respond(req, reply);
}

/// The status of a handler's error: 404, 413, 408 (the client too slow), else 400.
fn error_status(e: &anyhow::Error) -> u16 {
    if e.chain().any(|c| c.downcast_ref::<NotFound>().is_some()) {
        404
    } else if e.chain().any(|c| c.downcast_ref::<TooLarge>().is_some()) {
        413
    } else if e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::TimedOut)
    }) {
        408
    } else {
        400
    }
}

/// Whether `method path` streams an upload (its body is read by its handler, before the handler
/// takes a slot); every other body is small and read ahead.
fn is_upload(method: &str, path: &str) -> bool {
    let parts: Vec<&str> = path.trim_matches('/').split('/').collect();
    method.eq_ignore_ascii_case("POST")
        && matches!(
            parts.as_slice(),
            ["api", "frames"] | ["api", "frames", _, "flat" | "reference"]
        )
}

/// A request past the gate: its small body read (with a deadline) before a handler slot is
/// taken, so that a slow client holds no slot.
fn handle(studio: &Studio, req: &mut Request, t: &Target) -> Result<Reply> {
    if is_upload(req.method(), &t.path) {
        return route(studio, req, t);
    }
    req.buffer_body(MAX_JSON + 1, JSON_DEADLINE)
        .context("reading the request body")?;
    let _slot = studio.slots.take();
    route(studio, req, t)
}

fn respond(req: Request, reply: Reply) {
    let mut headers = vec![
        ("Content-Type", reply.content_type.to_string()),
        ("Cache-Control", "no-store".to_string()),
        ("X-Content-Type-Options", "nosniff".to_string()),
        ("Referrer-Policy", "no-referrer".to_string()),
        (
            "Content-Security-Policy",
            "default-src 'self'; img-src 'self' blob: data:; style-src 'self'; script-src 'self'; connect-src 'self'; frame-ancestors 'none'".to_string(),
        ),
    ];
    if let Some(f) = &reply.filename {
        headers.push((
            "Content-Disposition",
            format!(
                "attachment; filename=\"{}\"",
                f.replace(['"', '\\', '\r', '\n'], "_")
            ),
        ));
    }
    headers.extend(reply.extra);
    req.respond(reply.status, &headers, &reply.body);
}

/// A 404.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub(crate) struct NotFound(pub String);

/// A 413.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub(crate) struct TooLarge(pub String);

/// The page's files and the API: what is not about one open frame here, the rest in
/// [`route_frame`].
fn route(studio: &Studio, req: &mut Request, t: &Target) -> Result<Reply> {
    let method = req.method().to_ascii_uppercase();
    let parts: Vec<&str> = t.path.trim_matches('/').split('/').collect();
    match (method.as_str(), parts.as_slice()) {
        ("GET", [""]) | ("GET", ["index.html"]) => Ok(Reply::new(
            200,
            "text/html; charset=utf-8",
            INDEX_HTML.replace("{{TOKEN}}", &studio.token).into_bytes(),
        )),
        ("GET", ["app.js"]) => Ok(Reply::new(
            200,
            "text/javascript; charset=utf-8",
            APP_JS.as_bytes().to_vec(),
        )),
        ("GET", ["style.css"]) => Ok(Reply::new(
            200,
            "text/css; charset=utf-8",
            STYLE_CSS.as_bytes().to_vec(),
        )),
        ("GET", ["api", "info"]) => Ok(json(200, &studio.info())),
        ("POST", ["api", "frames"]) => {
            let name = t.param("name").map(str::to_string);
            let (dir, id) = studio.new_upload_dir()?;
            let saved = receive_upload(req, &dir, name, frame_limit(studio)).inspect_err(|_| {
                let _ = std::fs::remove_dir_all(&dir);
            })?;
            let _slot = studio.slots.take();
            Ok(json(200, &studio.open(id, saved, true)?))
        }
        ("POST", ["api", "files", n, "open"]) => {
            let i: usize = n
                .parse()
                .map_err(|_| BadRequest(format!("file index `{n}` is not a number")))?;
            let path =
                studio.files.get(i).cloned().ok_or_else(|| {
                    NotFound(format!("no file {i}: {} listed", studio.files.len()))
                })?;
            let id = studio.new_id();
            Ok(json(200, &studio.open(id, path, false)?))
        }
        (m, ["api", "frames", id, rest @ ..]) => route_frame(studio, req, t, m, id, rest),
        (_, ["api", ..]) => Err(NotFound(format!("no endpoint {method} {}", t.path)).into()),
        _ => Err(NotFound(format!("no page {}", t.path)).into()),
    }
}

/// The API of open frame `id`: `method` on `/api/frames/ID/REST…`.
fn route_frame(
    studio: &Studio,
    req: &mut Request,
    t: &Target,
    method: &str,
    id: &str,
    rest: &[&str],
) -> Result<Reply> {
    match (method, rest) {
        ("GET", []) => Ok(json(200, &studio.frame(id)?.lock_state().state())),
        ("DELETE", []) => {
            studio.close(id)?;
            Ok(json(200, &Closed { closed: id }))
        }
        ("POST", ["reading"]) => {
            let body = read_json(req)?;
            let f = studio.frame(id)?;
            let mut s = f.lock_state();
            s.set_reading(studio, body)?;
            Ok(json(200, &s.state()))
        }
        ("POST", [what @ ("flat" | "reference")]) => frame_upload(studio, req, t, id, what),
        ("GET", ["preview.png"]) => {
            let f = studio.frame(id)?;
            let png = f.lock_state().preview_png.clone();
            Ok(Reply::new(200, "image/png", png))
        }
        ("GET", ["overlay.png"]) => {
            let f = studio.frame(id)?;
            let png = f.lock_state().overlay_png()?;
            Ok(Reply::new(200, "image/png", png))
        }
        ("POST", ["fit"]) => {
            let body = read_json(req)?;
            let f = studio.frame(id)?;
            let mut s = f.lock_state();
            Ok(json(200, &s.fit(body)?))
        }
        ("POST", ["compare"]) => {
            let body = read_json(req)?;
            let f = studio.frame(id)?;
            // The frame's lock is held only to take the patches: other requests on this frame
            // (a corner drag, a preview) go on while the models are evaluated.
            let plan = f.lock_state().compare_plan(body)?;
            Ok(json(200, &plan.run()))
        }
        ("GET", ["corrected.png"]) => {
            let f = studio.frame(id)?;
            let s = f.lock_state();
            let (png, computed) =
                s.corrected_png(studio, t.param("space").unwrap_or("linear-srgb"))?;
            let mut r = Reply::new(200, "image/png", png);
            r.extra.push(("X-Nsrm-Device", computed.device.to_string()));
            r.extra
                .push(("X-Nsrm-Device-Detail", header_text(&computed.detail)));
            Ok(r)
        }
        ("GET", ["export"]) => {
            let f = studio.frame(id)?;
            let s = f.lock_state();
            let (bytes, name) = s.export(t)?;
            Ok(Reply::download("application/octet-stream", bytes, name))
        }
        ("GET", ["model.json"]) => {
            let f = studio.frame(id)?;
            let text = f.lock_state().model_json()?;
            Ok(Reply::download(
                "application/json",
                text.into_bytes(),
                "model.json".into(),
            ))
        }
        ("GET", ["patches.csv"]) => {
            let f = studio.frame(id)?;
            let text = f.lock_state().patches_csv()?;
            Ok(Reply::download(
                "text/csv",
                text.into_bytes(),
                "patches.csv".into(),
            ))
        }
        ("GET", ["command"]) => {
            let f = studio.frame(id)?;
            let text = f.lock_state().command(t);
            Ok(Reply::new(
                200,
                "text/plain; charset=utf-8",
                text.into_bytes(),
            ))
        }
        ("GET", ["shader"]) => {
            let f = studio.frame(id)?;
            let v = f
                .lock_state()
                .wgsl(t.param("space").unwrap_or("linear-srgb"))?;
            Ok(json(200, &v))
        }
        ("GET", ["pixels.f32"]) => {
            let f = studio.frame(id)?;
            let (bytes, w, h) = f.lock_state().preview_pixels();
            let mut r = Reply::new(200, "application/octet-stream", bytes);
            r.extra.push(("X-Nsrm-Width", w.to_string()));
            r.extra.push(("X-Nsrm-Height", h.to_string()));
            Ok(r)
        }
        _ => Err(NotFound(format!("no endpoint {method} {}", t.path)).into()),
    }
}

/// `text` as a header value: printable ASCII (anything else `?`), at most 200 characters.
fn header_text(text: &str) -> String {
    text.chars()
        .map(|c| {
            if c.is_ascii_graphic() || c == ' ' {
                c
            } else {
                '?'
            }
        })
        .take(200)
        .collect()
}

/// A JSON body (at most [`MAX_JSON`] bytes; an empty body is `{}`).
fn read_json(req: &mut Request) -> Result<serde_json::Value> {
    if req.body_length().is_some_and(|n| n > MAX_JSON) {
        return Err(TooLarge(format!("a JSON body over {MAX_JSON} bytes")).into());
    }
    let mut buf = Vec::new();
    req.as_reader()
        .take(MAX_JSON + 1)
        .read_to_end(&mut buf)
        .context("reading the request body")?;
    if buf.len() as u64 > MAX_JSON {
        return Err(TooLarge(format!("a JSON body over {MAX_JSON} bytes")).into());
    }
    if buf.iter().all(u8::is_ascii_whitespace) {
        return Ok(serde_json::Value::Object(serde_json::Map::new()));
    }
    serde_json::from_slice(&buf)
        .map_err(|e| BadRequest(format!("the request body is not JSON: {e}")).into())
}

/// A file name safe to create in our directory: the last component, odd characters replaced.
pub(crate) fn safe_name(name: &str) -> String {
    let last = name.rsplit(['/', '\\']).next().unwrap_or("");
    let s: String = last
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || matches!(c, '.' | '-' | '_') {
                c
            } else {
                '_'
            }
        })
        .take(100)
        .collect();
    let s = s.trim_start_matches('.').to_string();
    if s.is_empty() {
        "upload".into()
    } else {
        s
    }
}

/// `POST /api/frames/ID/flat` or `/reference`: the upload received into the frame's folder
/// (before the frame is locked: a slow upload blocks nothing else), then read as `--flat` or
/// `--reference` reads one; a refused file leaves nothing behind.
fn frame_upload(
    studio: &Studio,
    req: &mut Request,
    t: &Target,
    id: &str,
    what: &str,
) -> Result<Reply> {
    let f = studio.frame(id)?;
    let name = t.param("name").map(str::to_string);
    let dir = studio.new_frame_dir(id, what)?;
    let limit = if what == "flat" {
        frame_limit(studio)
    } else {
        Limit {
            bytes: MAX_REFERENCE_BYTES,
            what: "a reference file".into(),
        }
    };
    let saved = receive_upload(req, &dir, name, limit).inspect_err(|_| {
        let _ = std::fs::remove_dir_all(&dir);
    })?;
    let _slot = studio.slots.take();
    let mut s = f.lock_state();
    let set = if what == "flat" {
        s.set_flat_upload(&saved)
    } else {
        s.set_reference_upload(&saved)
    };
    set.inspect_err(|_| {
        let _ = std::fs::remove_dir_all(&dir);
    })?;
    Ok(json(200, &s.state()))
}

/// The largest reference file the studio takes (a chart's values are a few kilobytes).
const MAX_REFERENCE_BYTES: u64 = 1 << 20;

/// What an upload may hold: its bytes, and what the limit is (for the refusal).
struct Limit {
    bytes: u64,
    what: String,
}

/// The limit of a frame upload: a frame at the pixel limit ([`Studio::max_upload_bytes`]).
fn frame_limit(studio: &Studio) -> Limit {
    Limit {
        bytes: studio.max_upload_bytes(),
        what: format!("the frame limit of {} pixels", studio.max_pixels),
    }
}

/// Streams the upload (the raw body, or the multipart field `file`) into `dir`, at most
/// `limit`'s bytes. Returns the file's path.
fn receive_upload(
    req: &mut Request,
    dir: &Path,
    name: Option<String>,
    limit: Limit,
) -> Result<std::path::PathBuf> {
    let Limit { bytes: limit, what } = limit;
    if req
        .body_length()
        .is_some_and(|n| n > limit.saturating_add(64 * 1024))
    {
        return Err(TooLarge(format!(
            "the upload ({} bytes) is over the limit of {limit} bytes ({what})",
            req.body_length().unwrap_or(0),
        ))
        .into());
    }
    let ctype = header(req, "Content-Type").unwrap_or("").to_string();
    let boundary = ctype
        .to_ascii_lowercase()
        .starts_with("multipart/form-data")
        .then(|| {
            ctype.split(';').find_map(|p| {
                p.trim()
                    .strip_prefix("boundary=")
                    .map(|b| b.trim_matches('"').to_string())
            })
        });
    req.set_body_deadline(UPLOAD_BASE + Duration::from_secs(limit / UPLOAD_RATE));
    let reader = req.as_reader();
    let (name, path) = match boundary {
        Some(None) => bail!(BadRequest("a multipart body without a boundary".into())),
        Some(Some(b)) => {
            if b.is_empty() || b.len() > 200 {
                bail!(BadRequest("a multipart boundary of a bad length".into()));
            }
            multipart_file(reader, &b, dir, limit)?
        }
        None => {
            let name = safe_name(name.as_deref().unwrap_or("upload"));
            let path = dir.join(&name);
            copy_bounded(reader, &path, limit, None)?;
            (name, path)
        }
    };
    let _ = name;
    if std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0) == 0 {
        bail!(BadRequest("the upload is empty".into()));
    }
    Ok(path)
}

/// Copies `r` into a new file at `path`, at most `limit` bytes (else [`TooLarge`]), stopping at
/// `delimiter` if given (which must then be found). On any error the partial file is removed.
fn copy_bounded(r: &mut dyn Read, path: &Path, limit: u64, delimiter: Option<&[u8]>) -> Result<()> {
    let created = std::cell::Cell::new(false);
    copy_bounded_inner(r, path, limit, delimiter, &created).inspect_err(|_| {
        if created.get() {
            let _ = std::fs::remove_file(path);
        }
    })
}

fn copy_bounded_inner(
    r: &mut dyn Read,
    path: &Path,
    limit: u64,
    delimiter: Option<&[u8]>,
    created: &std::cell::Cell<bool>,
) -> Result<()> {
    let mut f = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(path)
        .with_context(|| format!("creating {}", path.display()))?;
    created.set(true);
    let mut written = 0u64;
    let mut buf = vec![0u8; 1 << 16];
    let mut pending: Vec<u8> = Vec::new();
    loop {
        let n = r.read(&mut buf).context("reading the upload")?;
        if n == 0 {
            if delimiter.is_some() {
                bail!(BadRequest(
                    "a multipart body that ends inside its file".into()
                ));
            }
            f.write_all(&pending)?;
            break;
        }
        pending.extend_from_slice(&buf[..n]);
        if let Some(d) = delimiter {
            if let Some(at) = find(&pending, d) {
                written += at as u64;
                if written > limit {
                    bail!(TooLarge(format!(
                        "the upload is over the limit of {limit} bytes"
                    )));
                }
                f.write_all(&pending[..at])?;
                // Drain the rest of the body (the closing boundary), bounded.
                let _ = std::io::copy(&mut r.take(1 << 20), &mut std::io::sink());
                return Ok(());
            }
            // Keep the tail that could start a delimiter.
            let keep = d.len().saturating_sub(1).min(pending.len());
            let flush = pending.len() - keep;
            written += flush as u64;
            if written > limit {
                bail!(TooLarge(format!(
                    "the upload is over the limit of {limit} bytes"
                )));
            }
            f.write_all(&pending[..flush])?;
            pending.drain(..flush);
        } else {
            written += pending.len() as u64;
            if written > limit {
                bail!(TooLarge(format!(
                    "the upload is over the limit of {limit} bytes"
                )));
            }
            f.write_all(&pending)?;
            pending.clear();
        }
    }
    Ok(())
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    if needle.is_empty() || hay.len() < needle.len() {
        return None;
    }
    hay.windows(needle.len()).position(|w| w == needle)
}

/// Reads a `multipart/form-data` body up to its field `file` and streams that field's content to
/// `dir/<its file name>`.
fn multipart_file(
    r: &mut dyn Read,
    boundary: &str,
    dir: &Path,
    limit: u64,
) -> Result<(String, std::path::PathBuf)> {
    let dash = format!("--{boundary}");
    let delim = format!("\r\n--{boundary}");
    // Parts before `file` (small form fields) are skipped; their bytes are bounded.
    let mut head: Vec<u8> = Vec::new();
    let mut byte = [0u8; 1];
    let mut seen = 0usize;
    loop {
        // Read up to the end of this part's headers.
        while !head.ends_with(b"\r\n\r\n") {
            if r.read(&mut byte).context("reading the upload")? == 0 {
                bail!(BadRequest("a multipart body without a field `file`".into()));
            }
            head.push(byte[0]);
            seen += 1;
            if seen > 1 << 20 {
                bail!(BadRequest(
                    "a multipart body whose first MiB holds no field `file`".into()
                ));
            }
        }
        let text = String::from_utf8_lossy(&head).into_owned();
        let disp = text
            .lines()
            .find(|l| l.to_ascii_lowercase().starts_with("content-disposition:"))
            .unwrap_or("")
            .to_string();
        let field = |key: &str| -> Option<String> {
            disp.split(';').find_map(|p| {
                let p = p.trim();
                p.strip_prefix(&format!("{key}="))
                    .map(|v| v.trim_matches('"').to_string())
            })
        };
        if !text.contains(&dash) {
            bail!(BadRequest("a malformed multipart body".into()));
        }
        if field("name").as_deref() == Some("file") {
            let name = safe_name(&field("filename").unwrap_or_else(|| "upload".into()));
            let path = dir.join(&name);
            copy_bounded(r, &path, limit, Some(delim.as_bytes()))?;
            return Ok((name, path));
        }
        // Skip this part: read to the next delimiter, bounded.
        let mut skipped = Vec::new();
        loop {
            if r.read(&mut byte).context("reading the upload")? == 0 {
                return Err(anyhow!(BadRequest(
                    "a multipart body without a field `file`".into()
                )));
            }
            skipped.push(byte[0]);
            seen += 1;
            if seen > 1 << 20 {
                bail!(BadRequest(
                    "a multipart body whose first MiB holds no field `file`".into()
                ));
            }
            if skipped.ends_with(delim.as_bytes()) {
                break;
            }
        }
        head = dash.as_bytes().to_vec();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hosts() {
        assert!(local_host("127.0.0.1:8080", 8080));
        assert!(local_host("localhost:8080", 8080));
        assert!(local_host("[::1]:8080", 8080));
        assert!(!local_host("127.0.0.1:8081", 8080));
        assert!(!local_host("evil.example:8080", 8080));
        assert!(!local_host("127.0.0.1.evil.example:8080", 8080));
        assert!(!local_host("", 8080));
    }

    #[test]
    fn names() {
        assert_eq!(safe_name("../../etc/passwd"), "passwd");
        assert_eq!(safe_name("..\\x.exr"), "x.exr");
        assert_eq!(safe_name(".."), "upload");
        assert_eq!(safe_name("a b.exr"), "a_b.exr");
        assert_eq!(percent_decode("a%20b+c%zz%4"), "a b c%zz%4");
    }

    #[test]
    fn multipart() {
        let dir = std::env::temp_dir().join(format!("nsrm-studio-mp-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let body = b"--XyZ\r\nContent-Disposition: form-data; name=\"note\"\r\n\r\nhello\r\n--XyZ\r\nContent-Disposition: form-data; name=\"file\"; filename=\"../s.exr\"\r\nContent-Type: application/octet-stream\r\n\r\nDATA\r\n--XyZ\r\nbytes\r\n--XyZ--\r\n";
        let (name, path) = multipart_file(&mut &body[..], "XyZ", &dir, 100).unwrap();
        assert_eq!(name, "s.exr");
        assert_eq!(std::fs::read(&path).unwrap(), b"DATA");
        let e = multipart_file(&mut &b"--XyZ\r\n\r\n"[..], "XyZ", &dir, 100);
        assert!(e.is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn header_text_is_printable_ascii_of_bounded_length() {
        assert_eq!(header_text("lavapipe (LLVM 17)"), "lavapipe (LLVM 17)");
        assert_eq!(header_text("GPU\r\nX-Evil: 1 – é"), "GPU??X-Evil: 1 ? ?");
        assert_eq!(header_text(&"a".repeat(300)).len(), 200);
    }
}
