//! The load test's own HTTP/1.1 client: one keep-alive connection per simulated client,
//! requests encoded once up front, answers framed by `Content-Length` or chunked encoding; and
//! the servers it drives (`--url`, a comma-separated list of loopback base URLs, the clients
//! spread round-robin over them).
//! The load generator shares the machine with the server it measures; a general-purpose client
//! (reqwest) spent ~90 µs of CPU per request here, this one a few, so the measurement reflects
//! the server rather than the generator.

use std::io;

use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

/// One server the load goes to, from an `http://host[:port][/prefix]` base URL.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Target {
    /// The base URL without a trailing `/`.
    pub base: String,
    /// `host:port` to connect to (port 80 when the URL names none).
    pub addr: String,
    /// Path prefix of the API (`""` or `/something`).
    pub prefix: String,
}

/// The servers of `--url`: a comma-separated list of `http://` base URLs on the loopback
/// interface (blanks around the commas ignored), each named once.
pub fn parse_targets(urls: &str) -> Result<Vec<Target>, String> {
    let mut out: Vec<Target> = Vec::new();
    for url in urls.split(',').map(str::trim) {
        if url.is_empty() {
            return Err(format!("--url: an empty entry in '{urls}'"));
        }
        let t = parse_target(url)?;
        if out.iter().any(|o| o.base == t.base) {
            return Err(format!("--url: '{}' is named twice", t.base));
        }
        out.push(t);
    }
    Ok(out)
}

fn parse_target(url: &str) -> Result<Target, String> {
    let base = url.trim_end_matches('/').to_string();
    let rest = base
        .strip_prefix("http://")
        .ok_or_else(|| format!("--url: only http:// URLs of a local server (got '{url}')"))?;
    let (host, path) = rest.split_once('/').unwrap_or((rest, ""));
    // `[::1]` alone has colons but no port.
    let (name, port) = match host.rsplit_once(':') {
        Some((h, p)) if !host.ends_with(']') => (h, Some(p)),
        _ => (host, None),
    };
    if !matches!(name, "127.0.0.1" | "localhost" | "[::1]") {
        return Err(format!(
            "--url: the load test only drives a server on the loopback interface (got host '{name}')"
        ));
    }
    let addr = match port {
        Some(p) if p.parse::<u16>().is_ok() => host.to_string(),
        Some(p) => return Err(format!("--url: bad port '{p}' in '{url}'")),
        None => format!("{host}:80"),
    };
    let prefix = path.trim_end_matches('/');
    let prefix = if prefix.is_empty() {
        String::new()
    } else {
        format!("/{prefix}")
    };
    Ok(Target { base, addr, prefix })
}

/// The server of client `i` among `n`: round-robin.
pub fn target_of(client: usize, n: usize) -> usize {
    client % n.max(1)
}

/// Largest head (status line + headers) and body accepted from the server.
const MAX_HEAD: usize = 64 * 1024;
const MAX_BODY: usize = 64 * 1024 * 1024;

/// An encoded `POST` request.
pub fn encode_post(host: &str, path: &str, auth: Option<&str>, body: &[u8]) -> Vec<u8> {
    let mut r = format!(
        "POST {path} HTTP/1.1\r\nhost: {host}\r\ncontent-type: application/json\r\ncontent-length: {}\r\n",
        body.len()
    );
    if let Some(a) = auth {
        r.push_str("authorization: ");
        r.push_str(a);
        r.push_str("\r\n");
    }
    r.push_str("\r\n");
    let mut v = r.into_bytes();
    v.extend_from_slice(body);
    v
}

fn bad(msg: &str) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidData, msg.to_string())
}

/// One keep-alive connection; reconnects after an error or a `connection: close`.
pub struct Conn {
    addr: String,
    stream: Option<TcpStream>,
    /// Bytes read and not yet consumed.
    buf: Vec<u8>,
    body: Vec<u8>,
}

impl Conn {
    /// `addr`: `host:port`.
    pub fn new(addr: &str) -> Conn {
        Conn {
            addr: addr.to_string(),
            stream: None,
            buf: Vec::with_capacity(8192),
            body: Vec::with_capacity(8192),
        }
    }

    /// Sends an encoded request and reads the answer: its status and body.
    pub async fn send(&mut self, request: &[u8]) -> io::Result<(u16, &[u8])> {
        match self.exchange(request).await {
            Ok(status) => Ok((status, &self.body)),
            Err(e) => {
                self.stream = None;
                self.buf.clear();
                Err(e)
            }
        }
    }

    async fn fill(&mut self) -> io::Result<()> {
        let s = self.stream.as_mut().ok_or_else(|| bad("not connected"))?;
        let mut chunk = [0u8; 8192];
        let n = s.read(&mut chunk).await?;
        if n == 0 {
            return Err(io::Error::new(
                io::ErrorKind::UnexpectedEof,
                "server closed the connection",
            ));
        }
        self.buf.extend_from_slice(&chunk[..n]);
        Ok(())
    }

    /// Reads until `buf` holds at least `n` bytes.
    async fn need(&mut self, n: usize) -> io::Result<()> {
        while self.buf.len() < n {
            self.fill().await?;
        }
        Ok(())
    }

    /// Reads one CRLF-terminated line off `buf` (without the CRLF).
    async fn line(&mut self) -> io::Result<String> {
        loop {
            if let Some(i) = self.buf.windows(2).position(|w| w == b"\r\n") {
                let l = String::from_utf8_lossy(&self.buf[..i]).into_owned();
                self.buf.drain(..i + 2);
                return Ok(l);
            }
            if self.buf.len() > MAX_HEAD {
                return Err(bad("line too long"));
            }
            self.fill().await?;
        }
    }

    async fn exchange(&mut self, request: &[u8]) -> io::Result<u16> {
        if self.stream.is_none() {
            let s = TcpStream::connect(&self.addr).await?;
            s.set_nodelay(true)?;
            self.stream = Some(s);
            self.buf.clear();
        }
        if let Some(s) = self.stream.as_mut() {
            s.write_all(request).await?;
        }
        // Head.
        let head_end = loop {
            if let Some(i) = self.buf.windows(4).position(|w| w == b"\r\n\r\n") {
                break i;
            }
            if self.buf.len() > MAX_HEAD {
                return Err(bad("response head too long"));
            }
            self.fill().await?;
        };
        let head = String::from_utf8_lossy(&self.buf[..head_end]).into_owned();
        self.buf.drain(..head_end + 4);
        let mut lines = head.split("\r\n");
        let status = lines
            .next()
            .and_then(|l| l.split(' ').nth(1))
            .and_then(|c| c.parse::<u16>().ok())
            .ok_or_else(|| bad("malformed status line"))?;
        let (mut length, mut chunked, mut close) = (None, false, false);
        for l in lines {
            let Some((k, v)) = l.split_once(':') else {
                continue;
            };
            let (k, v) = (k.trim().to_ascii_lowercase(), v.trim().to_ascii_lowercase());
            match k.as_str() {
                "content-length" => {
                    length = Some(v.parse::<usize>().map_err(|_| bad("bad content-length"))?)
                }
                "transfer-encoding" => chunked = v.contains("chunked"),
                "connection" => close = v.contains("close"),
                _ => {}
            }
        }
        // Body.
        self.body.clear();
        if chunked {
            loop {
                let size_line = self.line().await?;
                let size =
                    usize::from_str_radix(size_line.split(';').next().unwrap_or("").trim(), 16)
                        .map_err(|_| bad("bad chunk size"))?;
                if self.body.len() + size > MAX_BODY {
                    return Err(bad("response body too large"));
                }
                if size == 0 {
                    // Trailers up to the empty line.
                    while !self.line().await?.is_empty() {}
                    break;
                }
                self.need(size + 2).await?;
                self.body.extend_from_slice(&self.buf[..size]);
                self.buf.drain(..size + 2);
            }
        } else if let Some(n) = length {
            if n > MAX_BODY {
                return Err(bad("response body too large"));
            }
            self.need(n).await?;
            self.body.extend_from_slice(&self.buf[..n]);
            self.buf.drain(..n);
        } else if status >= 200 && status != 204 && status != 304 {
            // Delimited by the end of the connection.
            loop {
                match self.fill().await {
                    Ok(()) if self.buf.len() <= MAX_BODY => {}
                    Ok(()) => return Err(bad("response body too large")),
                    Err(e) if e.kind() == io::ErrorKind::UnexpectedEof => break,
                    Err(e) => return Err(e),
                }
            }
            self.body.append(&mut self.buf);
            close = true;
        }
        if close {
            self.stream = None;
            self.buf.clear();
        }
        Ok(status)
    }
}
