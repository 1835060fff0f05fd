//! Target `http`: the HTTP client of remote builds (`harness::remote::HttpFile`, on
//! `ureq`) decoding a mutated range answer, then the chunk behind it. Each input is the whole
//! byte stream a server sends back — status line, headers, body — for one chunk of an LPC
//! build; a one-shot loopback server writes it to the client's connection and closes it.
//! What the client accepts (a `206` with the `Content-Range` asked for and exactly that many
//! bytes) goes on, its checksum recomputed so that mutated bodies reach LZO and the cloud
//! decoder, as a local read would ([`methods::store::unpack`], `lpc::cloud::decode`).

use std::io::{Read, Write};
use std::net::TcpListener;
use std::time::Duration;

use harness::remote::HttpFile;
use methods::store::ChunkRef;

use crate::corpus::Seed;

/// Longest a request may take: a mutated `Content-Length` larger than the body makes the
/// client wait for bytes that never come, until the server closes (at once) or this.
const TIMEOUT: Duration = Duration::from_secs(5);

/// Chunks of the LPC build that become seeds.
const CHUNKS: usize = 6;

/// The answer a correct server gives to the range request of `r` in a repository of `total`
/// bytes whose stored bytes are `repo`.
fn answer(r: &ChunkRef, repo: &[u8]) -> Vec<u8> {
    let (start, end) = (r.offset as usize, r.offset as usize + r.stored as usize);
    let mut b = format!(
        "HTTP/1.1 206 Partial Content\r\nContent-Type: application/octet-stream\r\n\
         Content-Range: bytes {start}-{}/{}\r\nContent-Length: {}\r\nETag: \"1f-2c\"\r\n\
         Accept-Ranges: bytes\r\n\r\n",
        end - 1,
        repo.len(),
        end - start
    )
    .into_bytes();
    b.extend_from_slice(&repo[start..end]);
    b
}

/// Seeds: the answers for the first [`CHUNKS`] chunks of the LPC repository `repo` whose
/// chunks are `refs`, each with its chunk reference.
pub fn seeds(refs: &[ChunkRef], repo: &[u8]) -> (Vec<Seed>, Vec<(Vec<ChunkRef>, bool)>) {
    refs.iter()
        .take(CHUNKS)
        .enumerate()
        .map(|(i, r)| {
            (
                Seed {
                    name: format!("chunk{i}.http"),
                    bytes: answer(r, repo),
                },
                (vec![*r], false),
            )
        })
        .unzip()
}

/// Serves `reply` once on a loopback port and asks for `r`'s bytes through it; the bytes the
/// client accepted are unpacked and decoded. Errors are the expected outcome of most inputs.
pub fn run(reply: &[u8], r: &ChunkRef) -> Result<(), String> {
    let listener = TcpListener::bind("127.0.0.1:0").map_err(|e| format!("bind: {e}"))?;
    let addr = listener.local_addr().map_err(|e| e.to_string())?;
    let reply = reply.to_vec();
    let server = std::thread::spawn(move || {
        let Ok((mut s, _)) = listener.accept() else {
            return;
        };
        let _ = s.set_read_timeout(Some(TIMEOUT));
        // Read the request's head (bounded), then answer and close.
        let mut head = Vec::new();
        let mut b = [0u8; 512];
        while !head.windows(4).any(|w| w == b"\r\n\r\n") && head.len() < 64 * 1024 {
            match s.read(&mut b) {
                Ok(0) | Err(_) => break,
                Ok(n) => head.extend_from_slice(&b[..n]),
            }
        }
        let _ = s.write_all(&reply);
        let _ = s.shutdown(std::net::Shutdown::Both);
    });
    let file = HttpFile::new(format!("http://{addr}/repo.bin"), TIMEOUT);
    let got = file.get_range(r.offset, u64::from(r.stored));
    let _ = server.join();
    let body = got.map_err(|e| e.to_string())?;
    let sealed = ChunkRef {
        checksum: methods::store::checksum(&body),
        ..*r
    };
    let raw = methods::store::unpack(&body, &sealed, "chunk")?;
    methods::lpc::cloud::decode(0, &raw)
        .map(drop)
        .map_err(|e| e.to_string())
}
