//! The studio's HTTP/1.1 server on a loopback socket: one thread per connection (at most
//! [`MAX_CONNECTIONS`], beyond which a connection is answered 503 at once), one request per
//! connection (every answer closes it), and a fixed number of handler slots (`--threads`) taken
//! only once a request's headers passed the gate and its small body was read.
//!
//! Everything is bounded before it is read: the request line and headers by [`MAX_HEAD`] bytes
//! and [`HEAD_DEADLINE`]; every read of a body by [`IDLE`] and by the deadline its handler sets;
//! nothing is allocated at a size a header names. A request that is refused (the gate, a body
//! over its cap, a malformed head) is answered and closed without its body being read: the
//! connection lingers at most [`LINGER`] so that the client sees the answer, then is closed.

use std::io::{BufRead, BufReader, ErrorKind, Read, Write};
use std::net::{Shutdown, TcpListener, TcpStream};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

/// Connections served at once (each has a thread); one more is answered 503 and closed.
pub(crate) const MAX_CONNECTIONS: usize = 64;
/// Bytes of the request line and headers together.
const MAX_HEAD: usize = 32 * 1024;
/// Header lines.
const MAX_HEADERS: usize = 100;
/// The time a client has to send its request line and headers.
pub(crate) const HEAD_DEADLINE: Duration = Duration::from_secs(10);
/// The longest wait for the next bytes of a request.
pub(crate) const IDLE: Duration = Duration::from_secs(10);
/// How long a closed answer waits for the client to read it (its unread body is discarded
/// meanwhile, into a fixed buffer).
const LINGER: Duration = Duration::from_secs(2);

/// A parsed request: its head, and its body as a bounded reader.
pub(crate) struct Request {
    method: String,
    url: String,
    headers: Vec<(String, String)>,
    body_length: Option<u64>,
    body: Body,
}

/// The body of a request, read from the connection with a deadline.
pub(crate) struct Body {
    conn: BufReader<TcpStream>,
    framing: Framing,
    deadline: Instant,
    /// `Expect: 100-continue`: the interim answer is sent on the first read.
    send_continue: bool,
    /// A body read ahead into memory ([`Request::buffer_body`]).
    buffered: Option<std::io::Cursor<Vec<u8>>>,
}

enum Framing {
    /// This many bytes left.
    Length(u64),
    /// Chunked: bytes left in the current chunk (`None`: a chunk-size line is next).
    Chunked(Option<u64>),
    Done,
}

/// A request head the server refuses before any handler sees it.
#[derive(Debug)]
pub(crate) struct HeadError {
    pub(crate) status: u16,
    pub(crate) why: String,
}

fn head_error(status: u16, why: impl Into<String>) -> HeadError {
    HeadError {
        status,
        why: why.into(),
    }
}

/// A read error as the client's fault: a timeout becomes [`ErrorKind::TimedOut`].
fn timed_out(e: std::io::Error) -> std::io::Error {
    match e.kind() {
        ErrorKind::WouldBlock | ErrorKind::TimedOut => {
            std::io::Error::new(ErrorKind::TimedOut, "the client sent nothing for too long")
        }
        _ => e,
    }
}

/// Arms the socket's read timeout for the next read: the idle bound or what is left before
/// `deadline` (an error once it has passed).
fn arm(conn: &BufReader<TcpStream>, deadline: Instant) -> std::io::Result<()> {
    let left = deadline.saturating_duration_since(Instant::now());
    if left.is_zero() {
        return Err(std::io::Error::new(
            ErrorKind::TimedOut,
            "the client did not send its request in time",
        ));
    }
    conn.get_ref().set_read_timeout(Some(left.min(IDLE)))
}

/// One CRLF- (or LF-) terminated line, at most `max` bytes, before `deadline`.
fn read_line(
    conn: &mut BufReader<TcpStream>,
    max: usize,
    deadline: Instant,
) -> std::io::Result<Option<Vec<u8>>> {
    let mut line = Vec::new();
    loop {
        arm(conn, deadline)?;
        let buf = conn.fill_buf().map_err(timed_out)?;
        if buf.is_empty() {
            return Ok(None);
        }
        let (take, end) = match buf.iter().position(|&b| b == b'\n') {
            Some(i) => (i + 1, true),
            None => (buf.len(), false),
        };
        if line.len() + take > max {
            return Err(std::io::Error::new(
                ErrorKind::InvalidData,
                "a request line or header too long",
            ));
        }
        line.extend_from_slice(&buf[..take]);
        conn.consume(take);
        if end {
            while matches!(line.last(), Some(b'\n' | b'\r')) {
                line.pop();
            }
            return Ok(Some(line));
        }
    }
}

/// Reads a request's head from `stream`: `Ok(None)` when the client closed without one.
pub(crate) fn read_request(stream: TcpStream) -> Result<Option<Request>, (TcpStream, HeadError)> {
    let mut conn = BufReader::with_capacity(64 * 1024, stream);
    match parse_head(&mut conn) {
        Ok(None) => Ok(None),
        Ok(Some(head)) => Ok(Some(Request {
            method: head.method,
            url: head.url,
            headers: head.headers,
            body_length: head.body_length,
            body: Body {
                conn,
                framing: head.framing,
                deadline: Instant::now() + IDLE,
                send_continue: head.send_continue,
                buffered: None,
            },
        })),
        Err(e) => Err((conn.into_inner(), e)),
    }
}

/// A request's head, read.
struct Head {
    method: String,
    url: String,
    headers: Vec<(String, String)>,
    framing: Framing,
    body_length: Option<u64>,
    send_continue: bool,
}

fn parse_head(conn: &mut BufReader<TcpStream>) -> Result<Option<Head>, HeadError> {
    let deadline = Instant::now() + HEAD_DEADLINE;
    let io = |e: std::io::Error| match e.kind() {
        ErrorKind::TimedOut => head_error(408, e.to_string()),
        ErrorKind::InvalidData => head_error(431, e.to_string()),
        _ => head_error(400, format!("reading the request: {e}")),
    };
    let mut used = 0usize;
    // Empty lines before a request line are allowed (RFC 9112 §2.2).
    let line = loop {
        let Some(l) = read_line(conn, MAX_HEAD, deadline).map_err(io)? else {
            return Ok(None);
        };
        used += l.len() + 2;
        if !l.is_empty() {
            break l;
        }
        if used > MAX_HEAD {
            return Err(head_error(431, "a request head too long"));
        }
    };
    let line = String::from_utf8(line).map_err(|_| head_error(400, "a request line not UTF-8"))?;
    let mut parts = line.split(' ');
    let (Some(method), Some(url), Some(version), None) =
        (parts.next(), parts.next(), parts.next(), parts.next())
    else {
        return Err(head_error(400, "a malformed request line"));
    };
    if !matches!(version, "HTTP/1.0" | "HTTP/1.1")
        || method.is_empty()
        || !method.bytes().all(|b| b.is_ascii_alphabetic())
        || !url.starts_with('/')
    {
        return Err(head_error(400, "a malformed request line"));
    }
    let mut headers = Vec::new();
    loop {
        let left = MAX_HEAD.saturating_sub(used);
        let l = read_line(conn, left, deadline)
            .map_err(io)?
            .ok_or_else(|| head_error(400, "the connection closed inside the request head"))?;
        used += l.len() + 2;
        if l.is_empty() {
            break;
        }
        if headers.len() >= MAX_HEADERS {
            return Err(head_error(431, "too many header lines"));
        }
        let text = String::from_utf8(l).map_err(|_| head_error(400, "a header not UTF-8"))?;
        let (k, v) = text
            .split_once(':')
            .filter(|(k, _)| !k.is_empty() && !k.contains([' ', '\t']))
            .ok_or_else(|| head_error(400, "a malformed header line"))?;
        headers.push((k.to_string(), v.trim().to_string()));
    }
    let (framing, body_length) = framing(&headers)?;
    let send_continue =
        find(&headers, "Expect").is_some_and(|v| v.eq_ignore_ascii_case("100-continue"));
    Ok(Some(Head {
        method: method.to_string(),
        url: url.to_string(),
        headers,
        framing,
        body_length,
        send_continue,
    }))
}

fn find<'a>(headers: &'a [(String, String)], name: &str) -> Option<&'a str> {
    headers
        .iter()
        .find(|(k, _)| k.eq_ignore_ascii_case(name))
        .map(|(_, v)| v.as_str())
}

/// How the body is framed: `Transfer-Encoding: chunked`, a `Content-Length` (parsed as a
/// number, never used as an allocation size), or none.
fn framing(headers: &[(String, String)]) -> Result<(Framing, Option<u64>), HeadError> {
    let te: Vec<&str> = headers
        .iter()
        .filter(|(k, _)| k.eq_ignore_ascii_case("Transfer-Encoding"))
        .map(|(_, v)| v.as_str())
        .collect();
    let cl: Vec<&str> = headers
        .iter()
        .filter(|(k, _)| k.eq_ignore_ascii_case("Content-Length"))
        .map(|(_, v)| v.as_str())
        .collect();
    if !te.is_empty() {
        if !cl.is_empty() {
            return Err(head_error(400, "both Transfer-Encoding and Content-Length"));
        }
        if te.len() != 1 || !te[0].eq_ignore_ascii_case("chunked") {
            return Err(head_error(501, "a transfer encoding other than chunked"));
        }
        return Ok((Framing::Chunked(None), None));
    }
    let Some(first) = cl.first() else {
        return Ok((Framing::Done, None));
    };
    if cl.iter().any(|v| v != first) {
        return Err(head_error(400, "conflicting Content-Length headers"));
    }
    if first.is_empty() || first.len() > 20 || !first.bytes().all(|b| b.is_ascii_digit()) {
        return Err(head_error(
            400,
            format!("Content-Length `{first}`: not a byte count"),
        ));
    }
    let n: u64 = first
        .parse()
        .map_err(|_| head_error(413, format!("Content-Length `{first}`: too large")))?;
    Ok((
        if n == 0 {
            Framing::Done
        } else {
            Framing::Length(n)
        },
        Some(n),
    ))
}

impl Request {
    pub(crate) fn method(&self) -> &str {
        &self.method
    }

    pub(crate) fn url(&self) -> &str {
        &self.url
    }

    /// The first header `name` (case-insensitive).
    pub(crate) fn header(&self, name: &str) -> Option<&str> {
        find(&self.headers, name)
    }

    /// The declared `Content-Length` (none for a chunked body).
    pub(crate) fn body_length(&self) -> Option<u64> {
        self.body_length
    }

    /// Until when the body may be read (from now: `within`).
    pub(crate) fn set_body_deadline(&mut self, within: Duration) {
        self.body.deadline = Instant::now() + within;
    }

    pub(crate) fn as_reader(&mut self) -> &mut dyn Read {
        &mut self.body
    }

    /// Reads at most `max` bytes of the body ahead into memory (a body declared longer is left
    /// unread, for its handler to refuse).
    pub(crate) fn buffer_body(&mut self, max: u64, within: Duration) -> std::io::Result<()> {
        if self.body_length.is_some_and(|n| n > max) {
            return Ok(());
        }
        self.set_body_deadline(within);
        let mut buf = Vec::new();
        (&mut self.body).take(max).read_to_end(&mut buf)?;
        self.body.buffered = Some(std::io::Cursor::new(buf));
        Ok(())
    }

    /// Sends the answer (`Connection: close`) and closes the connection without reading the
    /// rest of the body.
    pub(crate) fn respond(self, status: u16, headers: &[(&str, String)], body: &[u8]) {
        let stream = self.body.conn.into_inner();
        write_answer(&stream, status, headers, body);
        linger_close(stream);
    }
}

/// Writes an answer (header values with control characters are left out).
pub(crate) fn write_answer(
    mut stream: &TcpStream,
    status: u16,
    headers: &[(&str, String)],
    body: &[u8],
) {
    let mut head = format!(
        "HTTP/1.1 {status} {}\r\nContent-Length: {}\r\nConnection: close\r\n",
        reason(status),
        body.len()
    );
    for (k, v) in headers {
        if v.chars().any(|c| c.is_control()) || k.chars().any(|c| !c.is_ascii_graphic()) {
            continue;
        }
        head.push_str(&format!("{k}: {v}\r\n"));
    }
    head.push_str("\r\n");
    let _ = stream.set_write_timeout(Some(IDLE));
    // The client may have gone away; nothing to do then.
    let _ = stream.write_all(head.as_bytes());
    let _ = stream.write_all(body);
    let _ = stream.flush();
}

/// Ends the connection: no more writing, what the client still sends discarded into a fixed
/// buffer for at most [`LINGER`] (so that the close does not reset the answer away), then closed.
pub(crate) fn linger_close(mut stream: TcpStream) {
    let _ = stream.shutdown(Shutdown::Write);
    let end = Instant::now() + LINGER;
    let mut sink = [0u8; 16 * 1024];
    loop {
        let left = end.saturating_duration_since(Instant::now());
        if left.is_zero() || stream.set_read_timeout(Some(left)).is_err() {
            break;
        }
        match stream.read(&mut sink) {
            Ok(0) | Err(_) => break,
            Ok(_) => {}
        }
    }
}

fn reason(status: u16) -> &'static str {
    match status {
        100 => "Continue",
        200 => "OK",
        400 => "Bad Request",
        403 => "Forbidden",
        404 => "Not Found",
        408 => "Request Timeout",
        413 => "Content Too Large",
        431 => "Request Header Fields Too Large",
        500 => "Internal Server Error",
        501 => "Not Implemented",
        503 => "Service Unavailable",
        _ => "",
    }
}

impl Body {
    /// One read from the connection, bounded by the idle time and the deadline; the
    /// connection's end inside the body is an error.
    fn raw_read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        self.continue_once()?;
        arm(&self.conn, self.deadline)?;
        let n = self.conn.read(buf).map_err(timed_out)?;
        if n == 0 && !buf.is_empty() {
            return Err(std::io::Error::new(
                ErrorKind::UnexpectedEof,
                "the client closed the connection inside the request body",
            ));
        }
        Ok(n)
    }

    /// `Expect: 100-continue`: the interim answer, before the body's first byte is read.
    fn continue_once(&mut self) -> std::io::Result<()> {
        if self.send_continue {
            self.send_continue = false;
            let mut s = self.conn.get_ref();
            s.write_all(b"HTTP/1.1 100 Continue\r\n\r\n")?;
        }
        Ok(())
    }

    /// The next chunk's size (its line, then any trailers after the last chunk).
    fn chunk_size(&mut self) -> std::io::Result<u64> {
        let bad = |why: &str| std::io::Error::new(ErrorKind::InvalidData, why.to_string());
        self.continue_once()?;
        let line = read_line(&mut self.conn, 1024, self.deadline)?
            .ok_or_else(|| bad("the connection closed inside a chunked body"))?;
        let text = String::from_utf8_lossy(&line);
        let hex = text.split(';').next().unwrap_or("").trim();
        if hex.is_empty() || hex.len() > 15 {
            return Err(bad("a malformed chunk size"));
        }
        let n = u64::from_str_radix(hex, 16).map_err(|_| bad("a malformed chunk size"))?;
        if n == 0 {
            // Trailers, up to the empty line.
            for _ in 0..MAX_HEADERS {
                match read_line(&mut self.conn, 8 * 1024, self.deadline)? {
                    Some(l) if !l.is_empty() => continue,
                    _ => return Ok(0),
                }
            }
            return Err(bad("too many trailer lines"));
        }
        Ok(n)
    }
}

impl Read for Body {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        if let Some(c) = &mut self.buffered {
            return c.read(buf);
        }
        loop {
            match self.framing {
                Framing::Done => return Ok(0),
                Framing::Length(left) => {
                    let want = buf.len().min(usize::try_from(left).unwrap_or(usize::MAX));
                    let n = self.raw_read(&mut buf[..want])?;
                    let left = left - n as u64;
                    self.framing = if left == 0 {
                        Framing::Done
                    } else {
                        Framing::Length(left)
                    };
                    return Ok(n);
                }
                Framing::Chunked(None) => {
                    let n = self.chunk_size()?;
                    self.framing = if n == 0 {
                        Framing::Done
                    } else {
                        Framing::Chunked(Some(n))
                    };
                }
                Framing::Chunked(Some(left)) => {
                    let want = buf.len().min(usize::try_from(left).unwrap_or(usize::MAX));
                    let n = self.raw_read(&mut buf[..want])?;
                    let left = left - n as u64;
                    if left == 0 {
                        // The CRLF after the chunk's data.
                        let l = read_line(&mut self.conn, 2, self.deadline)?;
                        if l.as_deref() != Some(&[][..]) {
                            return Err(std::io::Error::new(
                                ErrorKind::InvalidData,
                                "a chunk not followed by CRLF",
                            ));
                        }
                        self.framing = Framing::Chunked(None);
                    } else {
                        self.framing = Framing::Chunked(Some(left));
                    }
                    return Ok(n);
                }
            }
        }
    }
}

/// The handler slots (`--threads`): at most that many requests compute at once.
pub(crate) struct Slots {
    free: Mutex<usize>,
    freed: Condvar,
}

/// A taken slot, given back when dropped.
pub(crate) struct Slot<'a>(&'a Slots);

impl Slots {
    pub(crate) fn new(n: usize) -> Slots {
        Slots {
            free: Mutex::new(n.max(1)),
            freed: Condvar::new(),
        }
    }

    pub(crate) fn take(&self) -> Slot<'_> {
        let mut free = self.free.lock().unwrap_or_else(|e| e.into_inner());
        while *free == 0 {
            free = self.freed.wait(free).unwrap_or_else(|e| e.into_inner());
        }
        *free -= 1;
        Slot(self)
    }
}

impl Drop for Slot<'_> {
    fn drop(&mut self) {
        let mut free = self.0.free.lock().unwrap_or_else(|e| e.into_inner());
        *free += 1;
        self.0.freed.notify_one();
    }
}

/// Accepts connections for ever, each on a thread of its own running `handle` on its request
/// (at most [`MAX_CONNECTIONS`] at once).
pub(crate) fn accept_loop(listener: TcpListener, handle: Arc<dyn Fn(Request) + Send + Sync>) {
    let live = Arc::new(AtomicUsize::new(0));
    for stream in listener.incoming() {
        let Ok(stream) = stream else {
            // Out of descriptors or a connection reset before accept: go on after a pause.
            std::thread::sleep(Duration::from_millis(10));
            continue;
        };
        if live.fetch_add(1, Ordering::SeqCst) >= MAX_CONNECTIONS {
            live.fetch_sub(1, Ordering::SeqCst);
            let _ = stream.set_write_timeout(Some(Duration::from_millis(200)));
            write_answer(&stream, 503, &[], b"503: too many connections\n");
            let _ = stream.shutdown(Shutdown::Both);
            continue;
        }
        let (live2, handle) = (Arc::clone(&live), Arc::clone(&handle));
        let spawned = std::thread::Builder::new()
            .name("nsrm-studio-conn".into())
            .spawn(move || {
                connection(stream, &*handle);
                live2.fetch_sub(1, Ordering::SeqCst);
            });
        if spawned.is_err() {
            live.fetch_sub(1, Ordering::SeqCst);
        }
    }
}

fn connection(stream: TcpStream, handle: &(dyn Fn(Request) + Send + Sync)) {
    let _ = stream.set_nodelay(true);
    match read_request(stream) {
        Ok(Some(req)) => {
            // A panic in a handler ends this connection only.
            let _ = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| handle(req)));
        }
        Ok(None) => {}
        Err((stream, e)) => {
            let body = format!("{} {}: {}\n", e.status, reason(e.status), e.why);
            write_answer(
                &stream,
                e.status,
                &[("Content-Type", "text/plain; charset=utf-8".into())],
                body.as_bytes(),
            );
            linger_close(stream);
        }
    }
}
