// Asynchronous byte-range fetcher: streams the cells of a hierarchical-cells database (paper 003,
// shared/seeds/003; docs/cells.md) from an HTTP server or a local file, without ever blocking
// the caller (the frame loop).
//
// Source: "http://HOST[:PORT]/path" (HTTP/1.1, one keep-alive connection) or a local file path
// (local-disk mode: pread in the worker, the same API and results). One worker thread per
// fetcher; nothing (thread, socket, file) exists before open().
//
// Wire format (HTTP/1.1):
//   GET /path HTTP/1.1 | Host: HOST:PORT | Range: bytes=FIRST-LAST | Accept-Encoding: identity |
//   Connection: keep-alive
//   -> 206 Partial Content with Content-Range: bytes FIRST-LAST/TOTAL and Content-Length =
//      LAST - FIRST + 1 (anything else is a protocol error, found from the head before the body
//      is read: the connection is dropped and the requests on it retried). TOTAL gives
//      resourceBytes(). A 206 with FIRST-(TOTAL-1) for a range that runs past the end (what nginx
//      sends) refuses the requests past the end and delivers the others.
//   -> a response other than 206 with a body over 64 KiB (a 200 with the whole file) is handled
//      without reading the body; the connection is reopened.
//   -> 416 (Content-Range: bytes */TOTAL), 404, other 4xx and a 200 (the server ignored Range):
//      refused, the result has ok = false and an error naming the status and range; never retried.
//   -> 5xx, 408, 429: retried after a backoff.
// Efficiency for many small ranges: up to `pipelineDepth` requests are pipelined on the
// connection, and ranges that are adjacent in the file (or overlap, or lie within
// `coalesceGap_bytes` of each other) and wait together are coalesced into one GET of at most
// `maxCoalesce_bytes` (once the resource size is known, so that a merged range never runs past
// the end), then split into one result per request.
//
// Failures: connection refused, connect or I/O timeout (no byte for ioTimeout_s while requests
// are outstanding), a connection closed mid-response or a protocol error drop the connection;
// the requests on it are retried after an exponential backoff (retryMin_ms doubling to
// retryMax_ms; reset by the next good response). A connection the server closes after saying
// "Connection: close" is reopened at once and its unanswered requests resent without counting a
// retry; so is a keep-alive connection that answered before and is closed (or reset) by the
// server before a byte of the next response (a stale keep-alive: its idle timeout ran out as
// requests went out; they are resent on a fresh connection, not charged to maxAttempts). A
// connection closed mid-response charges only the request whose response had begun. A crc mismatch (zlib crc32 of the bytes) drops the data and fetches the range again
// (counted in `corrupt`) up to maxCorruptAttempts times. A request gives up (ok = false) after
// maxAttempts failed attempts (0 = never).
//
// Threads: submit(), poll(), resourceBytes() and stats() may be called from any one thread while
// the worker runs; they only take a mutex that the worker holds for short copies (never during
// I/O or a system call that can block). fetchSync() blocks (for start-up: header, index). A host
// name is resolved in the worker (getaddrinfo at each connect: it can delay the worker and the
// destructor, never submit() or poll()).
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace ig::io {

struct RangeRequest {
  uint32_t key = 0;       // the caller's id (e.g. a cell), returned in the result
  uint64_t offset = 0;    // first byte in the resource
  uint32_t size = 0;      // bytes, 1..maxRange_bytes
  uint32_t crc32 = 0;     // zlib crc32() of the bytes, checked when verifyCrc
  bool verifyCrc = true;
};

struct RangeResult {
  uint32_t key = 0;
  bool ok = false;
  std::vector<uint8_t> data;  // `size` bytes when ok
  std::string error;          // why not, when !ok (names the source, range and status)
};

struct RangeFetcherOptions {
  double connectTimeout_s = 2.0;         // a connect that takes longer fails (> 0)
  double ioTimeout_s = 10.0;             // no byte received for this long with requests outstanding: drop the connection (> 0)
  uint32_t retryMin_ms = 50;             // first backoff after a failure (>= 1)
  uint32_t retryMax_ms = 2000;           // backoff cap (>= retryMin_ms)
  uint32_t maxAttempts = 0;              // failed attempts before a request gives up; 0 = retry forever
  uint32_t maxCorruptAttempts = 3;       // crc mismatches before a request gives up; 0 = forever
  uint32_t pipelineDepth = 4;            // HTTP requests outstanding on the connection, 1..64
  uint32_t maxCoalesce_bytes = 256 << 10;  // largest coalesced GET; 0 = never coalesce
  uint32_t coalesceGap_bytes = 0;        // merge ranges at most this far apart (the gap is fetched and dropped)
  uint32_t maxRange_bytes = 64u << 20;   // larger requests are refused by submit() (1..1 GiB)
};

// Checks the ranges above; on error names the field and value, e.g. "pipelineDepth = 0: must be 1..64".
bool validRangeFetcherOptions(const RangeFetcherOptions& options, std::string& error);

struct RangeFetcherStats {
  uint64_t requests = 0;         // accepted by submit()
  uint64_t completed = 0;        // results handed out by poll(), ok or not
  uint64_t failed = 0;           // of those, ok = false
  uint64_t bytes = 0;            // payload bytes of ok results (fetchSync included)
  uint64_t wireRequests = 0;     // GETs sent (local mode: preads)
  uint64_t wireBytes = 0;        // bytes received from the server, heads included (local: read)
  uint64_t retries = 0;          // request attempts repeated after a failure (connection, 5xx, crc)
  uint64_t corrupt = 0;          // crc mismatches (the data was dropped and fetched again)
  uint64_t refused = 0;          // refused: 416, 404, other 4xx, 200 without range; or past the end once known
  uint64_t connectFailures = 0;  // connects that failed (refused, timeout, unresolvable host)
  uint64_t connections = 0;      // connections established
};

class RangeFetcher {
 public:
  // Parses the source, opens the file (local mode) and starts the worker. HTTP mode does not
  // connect yet (a server that is down is retried when requests come). Returns null with an
  // error naming the source and the bad part for a bad URL, options or an unreadable file.
  static std::unique_ptr<RangeFetcher> open(const std::string& source, const RangeFetcherOptions& options,
                                            std::string& error);
  ~RangeFetcher();  // stops and joins the worker; unfinished requests are dropped
  RangeFetcher(const RangeFetcher&) = delete;
  RangeFetcher& operator=(const RangeFetcher&) = delete;

  // Blocking read of one range (no crc), ahead of the queued requests, retried as above until
  // `timeout_s`. Not checked against resourceBytes(): a range past the end goes to the server
  // (which answers 416). Not for the frame loop. One call at a time.
  bool fetchSync(uint64_t offset, uint32_t size, std::vector<uint8_t>& out, std::string& error, double timeout_s);

  // Non-blocking: queues the request. Refuses (false, error names the key and range) a size of
  // 0 or above maxRange_bytes, and a range past the end once resourceBytes() is known
  // ("... the client refuses").
  bool submit(const RangeRequest& request, std::string& error);
  // All or nothing: queues every request (in order) or none (error names the first bad one).
  bool submit(std::span<const RangeRequest> requests, std::string& error);

  // Non-blocking: appends the finished requests (in completion order) and returns how many.
  // Reserve `out` to avoid allocation.
  size_t poll(std::vector<RangeResult>& out);

  // Size of the resource: from the first Content-Range "/TOTAL" (HTTP) or stat (local); 0 while
  // unknown.
  uint64_t resourceBytes() const;
  RangeFetcherStats stats() const;
  // Requests submitted and not yet handed out by poll().
  uint64_t outstanding() const;
  const std::string& source() const;

  struct Impl;

 private:
  explicit RangeFetcher(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// --- Pure parts, exposed for tests ---

struct HttpUrl {
  std::string host;  // name or address (IPv6 without brackets)
  uint16_t port = 80;
  std::string path;  // from the first '/', query included
};
// "http://HOST[:PORT]/path". On error names the source and the bad part.
bool parseHttpUrl(const std::string& source, HttpUrl& url, std::string& error);
// Whether the source names a URL ("scheme://...") rather than a file path.
bool looksLikeUrl(std::string_view source);

struct HttpResponseHead {
  int status = 0;
  int64_t contentLength = -1;    // -1: absent
  bool hasRange = false;         // Content-Range: bytes FIRST-LAST/...
  uint64_t rangeFirst = 0, rangeLast = 0;
  uint64_t total = 0;            // Content-Range "/TOTAL"; 0 with totalKnown false for "*" or absent
  bool totalKnown = false;
  bool close = false;            // the server will close the connection after this response
  bool chunked = false;          // Transfer-Encoding other than identity
  size_t headBytes = 0;          // status line + headers + the blank line
};
enum class HeadParse { Incomplete, Ok, Bad };
// Parses a response head at the start of `buf`. Incomplete: no blank line yet (and under 16 KB).
HeadParse parseHttpResponseHead(std::string_view buf, HttpResponseHead& head, std::string& error);

}  // namespace ig::io
