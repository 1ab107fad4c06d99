//! `hrc_zenoh_ffi`: a small C ABI over the `zenoh` crate (blocking API) for the hrc-cosim C++
//! services. The matching C header is `services/ik_cpp/include/hrc/zenoh_ffi.h`; keep both in sync.
//!
//! Conventions (see the header for the full contract):
//! - Every `hrcz_declare_*` / `hrcz_open` returns an owned handle or NULL; on NULL a NUL-terminated
//!   error text is written into the caller's `err` buffer (if not NULL). Each handle has exactly one
//!   matching free function (`hrcz_close`, `hrcz_undeclare_*`), which accepts NULL.
//! - No panic crosses the boundary: every entry point runs under `catch_unwind`.
//! - After `hrcz_undeclare_subscriber` / `hrcz_undeclare_queryable` returns, the C callback is never
//!   called again (a per-handle gate that undeclare closes while holding its lock). Consequence: do
//!   not undeclare a handle from inside its own callback (that would deadlock).
//! - Callbacks of one subscriber (or queryable) are serialised by that gate, never concurrent.
//!
//! Why one file of about 800 lines: it is the whole C ABI, one function per entry of the header,
//! best read side by side with `zenoh_ffi.h`; its tests are in `tests.rs`.

use std::ffi::{c_char, c_int, c_void, CStr};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use zenoh::bytes::ZBytes;
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::{Publisher, Subscriber};
use zenoh::qos::CongestionControl;
use zenoh::query::{Query, Queryable};
use zenoh::sample::{Sample, SampleKind};
use zenoh::{Config, Session, Wait};

// ------------------------------------------------------------------ helpers

/// Writes `msg` into the caller's buffer as a NUL-terminated string, truncating if needed.
fn write_err(err: *mut c_char, cap: usize, msg: &str) {
    if err.is_null() || cap == 0 {
        return;
    }
    let bytes = msg.as_bytes();
    let n = bytes.len().min(cap - 1);
    // SAFETY: the caller promises `err` points to `cap` writable bytes.
    unsafe {
        std::ptr::copy_nonoverlapping(bytes.as_ptr(), err as *mut u8, n);
        *err.add(n) = 0;
    }
}

fn panic_text(p: Box<dyn std::any::Any + Send>) -> String {
    if let Some(s) = p.downcast_ref::<&str>() {
        format!("internal panic: {s}")
    } else if let Some(s) = p.downcast_ref::<String>() {
        format!("internal panic: {s}")
    } else {
        "internal panic".to_string()
    }
}

/// Runs `f`, turning an error or a panic into `on_fail` plus an error text.
fn guarded<T>(
    err: *mut c_char,
    cap: usize,
    on_fail: T,
    f: impl FnOnce() -> Result<T, String>,
) -> T {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(Ok(v)) => v,
        Ok(Err(e)) => {
            write_err(err, cap, &e);
            on_fail
        }
        Err(p) => {
            write_err(err, cap, &panic_text(p));
            on_fail
        }
    }
}

/// Zenoh's own log on standard output (the service's log): what RUST_LOG asks for, by default
/// its errors, as in the Python services (a transport it closes because a message could not be
/// queued, and the messages lost with it, are said only there). Later calls change nothing.
fn init_log() {
    zenoh::init_log_from_env_or("error");
}

/// Borrow a C string argument as UTF-8, naming the argument in the error.
unsafe fn cstr<'a>(p: *const c_char, what: &str) -> Result<&'a str, String> {
    if p.is_null() {
        return Err(format!("{what} is NULL"));
    }
    CStr::from_ptr(p)
        .to_str()
        .map_err(|_| format!("{what} is not valid UTF-8"))
}

/// Borrow a (ptr, len) byte range; NULL is allowed only with len 0.
unsafe fn bytes<'a>(p: *const u8, len: usize, what: &str) -> Result<&'a [u8], String> {
    if len == 0 {
        return Ok(&[]);
    }
    if p.is_null() {
        return Err(format!("{what} is NULL but its length is {len}"));
    }
    Ok(std::slice::from_raw_parts(p, len))
}

/// The caller's opaque context pointer, moved into zenoh callback threads. The C side promises
/// that whatever it points to is safe to use from any thread while the handle is declared.
#[derive(Clone, Copy)]
struct Ctx(*mut c_void);
unsafe impl Send for Ctx {}
unsafe impl Sync for Ctx {}

/// Open while the handle is declared; undeclare closes it under the lock, so no callback runs
/// after undeclare returns, and callbacks of one handle never run concurrently.
#[derive(Clone)]
struct Gate(Arc<Mutex<bool>>);

impl Gate {
    fn new() -> Self {
        Gate(Arc::new(Mutex::new(true)))
    }

    /// Runs `f` under the gate's lock if the handle is still declared.
    fn pass(&self, f: impl FnOnce()) {
        let open = self.0.lock().unwrap_or_else(|p| p.into_inner());
        if *open {
            f();
        }
    }

    fn close(&self) {
        *self.0.lock().unwrap_or_else(|p| p.into_inner()) = false;
    }
}

fn zbytes_cow(z: Option<&ZBytes>) -> std::borrow::Cow<'_, [u8]> {
    match z {
        Some(z) => z.to_bytes(),
        None => std::borrow::Cow::Borrowed(&[]),
    }
}

// ------------------------------------------------------------------ session

/// Opaque session handle.
pub struct HrczSession {
    session: Session,
}

/// Opens a zenoh session from a JSON5 configuration text. Returns NULL on failure.
///
/// # Safety
/// Each pointer argument is NULL where the header allows it, or valid for the call:
/// strings NUL-terminated, buffers at least as long as their length argument, handles
/// returned by this library and not yet freed.
#[no_mangle]
pub unsafe extern "C" fn hrcz_open(
    config_json5: *const c_char,
    err: *mut c_char,
    err_cap: usize,
) -> *mut HrczSession {
    guarded(err, err_cap, std::ptr::null_mut(), || {
        let text = cstr(config_json5, "config_json5")?;
        init_log();
        let config = Config::from_json5(text).map_err(|e| format!("invalid zenoh config: {e}"))?;
        let session = zenoh::open(config)
            .wait()
            .map_err(|e| format!("cannot open zenoh session: {e}"))?;
        Ok(Box::into_raw(Box::new(HrczSession { session })))
    })
}

/// Opens a session the way the Python services do: start from the zenoh config file `base_file`
/// (NULL or "" = zenoh defaults), then apply `n` insertions `paths[i]` = `values_json5[i]`
/// (e.g. "mode" = "\"peer\""). Returns NULL on failure, naming the offending path.
///
/// # Safety
/// Each pointer argument is NULL where the header allows it, or valid for the call:
/// strings NUL-terminated, buffers at least as long as their length argument, handles
/// returned by this library and not yet freed.
#[no_mangle]
pub unsafe extern "C" fn hrcz_open_ex(
    base_file: *const c_char,
    paths: *const *const c_char,
    values_json5: *const *const c_char,
    n: usize,
    err: *mut c_char,
    err_cap: usize,
) -> *mut HrczSession {
    guarded(err, err_cap, std::ptr::null_mut(), || {
        init_log();
        let mut config = if base_file.is_null() || *base_file == 0 {
            Config::default()
        } else {
            let file = cstr(base_file, "base_file")?;
            Config::from_file(file)
                .map_err(|e| format!("invalid zenoh config file '{file}': {e}"))?
        };
        if n > 0 && (paths.is_null() || values_json5.is_null()) {
            return Err("paths or values_json5 is NULL".to_string());
        }
        for i in 0..n {
            let path = cstr(*paths.add(i), "config path")?;
            let value = cstr(*values_json5.add(i), "config value")?;
            config
                .insert_json5(path, value)
                .map_err(|e| format!("invalid zenoh config value for '{path}' ({value}): {e}"))?;
        }
        let session = zenoh::open(config)
            .wait()
            .map_err(|e| format!("cannot open zenoh session: {e}"))?;
        Ok(Box::into_raw(Box::new(HrczSession { session })))
    })
}

/// Closes and frees a session. Entities still declared on it stop working but must still be
/// freed with their own undeclare function. NULL is a no-op.
///
/// # Safety
/// The handle is NULL or one this library returned and not yet freed; it is invalid
/// afterwards.
#[no_mangle]
pub unsafe extern "C" fn hrcz_close(session: *mut HrczSession) {
    if session.is_null() {
        return;
    }
    let _ = catch_unwind(AssertUnwindSafe(|| {
        let s = Box::from_raw(session);
        let _ = s.session.close().wait();
        drop(s);
    }));
}

unsafe fn session_ref<'a>(s: *const HrczSession) -> Result<&'a HrczSession, String> {
    s.as_ref().ok_or_else(|| "session is NULL".to_string())
}

// ------------------------------------------------------------------ publisher

/// Opaque publisher handle.
pub struct HrczPublisher {
    publisher: Publisher<'static>,
}

/// Declares a publisher on `key`. `congestion_block` != 0: block when the queue is full instead
/// of dropping (reliable delivery); `express` != 0: do not batch (lower latency).
///
/// # Safety
/// Each pointer argument is NULL where the header allows it, or valid for the call:
/// strings NUL-terminated, buffers at least as long as their length argument, handles
/// returned by this library and not yet freed.
#[no_mangle]
pub unsafe extern "C" fn hrcz_declare_publisher(
    session: *const HrczSession,
    key: *const c_char,
    congestion_block: c_int,
    express: c_int,
    err: *mut c_char,
    err_cap: usize,
) -> *mut HrczPublisher {
    guarded(err, err_cap, std::ptr::null_mut(), || {
        let s = session_ref(session)?;
        let key = cstr(key, "key")?.to_string();
        let cc = if congestion_block != 0 {
            CongestionControl::Block
        } else {
            CongestionControl::Drop
        };
        let publisher = s
            .session
            .declare_publisher(key.clone())
            .congestion_control(cc)
            .express(express != 0)
            .wait()
            .map_err(|e| format!("cannot declare publisher on '{key}': {e}"))?;
        Ok(Box::into_raw(Box::new(HrczPublisher { publisher })))
    })
}

/// Publishes `payload` with `attachment` (may be empty). Returns 0 on success, -1 on error.
///
/// # Safety
/// Each pointer argument is NULL where the header allows it, or valid for the call:
/// strings NUL-terminated, buffers at least as long as their length argument, handles
/// returned by this library and not yet freed.
#[no_mangle]
pub unsafe extern "C" fn hrcz_publisher_put(
    publisher: *const HrczPublisher,
    payload: *const u8,
    len: usize,
    attachment: *const u8,
    att_len: usize,
    err: *mut c_char,
    err_cap: usize,
) -> c_int {
    guarded(err, err_cap, -1, || {
        let p = publisher.as_ref().ok_or("publisher is NULL")?;
        let data = bytes(payload, len, "payload")?;
        let att = bytes(attachment, att_len, "attachment")?;
        let mut put = p.publisher.put(data.to_vec());
        if !att.is_empty() {
            put = put.attachment(att.to_vec());
        }
        put.wait()
            .map_err(|e| format!("put on '{}' failed: {e}", p.publisher.key_expr()))?;
        Ok(0)
    })
}

/// 1 if at least one subscriber currently matches the publisher's key, 0 if none, -1 on error.
///
/// # Safety
/// Each pointer argument is NULL where the header allows it, or valid for the call:
/// strings NUL-terminated, buffers at least as long as their length argument, handles
/// returned by this library and not yet freed.
#[no_mangle]
pub unsafe extern "C" fn hrcz_publisher_has_subscribers(
    publisher: *const HrczPublisher,
    err: *mut c_char,
    err_cap: usize,
) -> c_int {
    guarded(err, err_cap, -1, || {
        let p = publisher.as_ref().ok_or("publisher is NULL")?;
        let status = p
            .publisher
            .matching_status()
            .wait()
            .map_err(|e| format!("matching status failed: {e}"))?;
        Ok(if status.matching() { 1 } else { 0 })
    })
}

/// Undeclares and frees a publisher. NULL is a no-op.
///
/// # Safety
/// The handle is NULL or one this library returned and not yet freed; it is invalid
/// afterwards.
#[no_mangle]
pub unsafe extern "C" fn hrcz_undeclare_publisher(publisher: *mut HrczPublisher) {
    if publisher.is_null() {
        return;
    }
    let _ = catch_unwind(AssertUnwindSafe(|| {
        let p = Box::from_raw(publisher);
        let _ = p.publisher.undeclare().wait();
    }));
}

// ------------------------------------------------------------------ subscribers

/// Data sample callback: key (not NUL-terminated), payload, attachment (empty if none).
pub type HrczSampleCallback = Option<
    unsafe extern "C" fn(
        ctx: *mut c_void,
        key: *const c_char,
        key_len: usize,
        payload: *const u8,
        len: usize,
        attachment: *const u8,
        att_len: usize,
    ),
>;

/// Liveliness callback: key of the token (not NUL-terminated), alive = 1 (appeared) / 0 (dropped).
pub type HrczLivelinessCallback = Option<
    unsafe extern "C" fn(ctx: *mut c_void, key: *const c_char, key_len: usize, alive: c_int),
>;

/// Opaque subscriber handle (data or liveliness).
pub struct HrczSubscriber {
    subscriber: Subscriber<()>,
    gate: Gate,
}

/// Declares a subscriber on a key expression; `callback(ctx, ...)` runs on a zenoh thread for
/// every sample until `hrcz_undeclare_subscriber` returns.
///
/// # Safety
/// Each pointer argument is NULL where the header allows it, or valid for the call:
/// strings NUL-terminated, buffers at least as long as their length argument, handles
/// returned by this library and not yet freed.
#[no_mangle]
pub unsafe extern "C" fn hrcz_declare_subscriber(
    session: *const HrczSession,
    key_expr: *const c_char,
    callback: HrczSampleCallback,
    ctx: *mut c_void,
    err: *mut c_char,
    err_cap: usize,
) -> *mut HrczSubscriber {
    guarded(err, err_cap, std::ptr::null_mut(), || {
        let s = session_ref(session)?;
        let key = cstr(key_expr, "key_expr")?.to_string();
        let cb = callback.ok_or("callback is NULL")?;
        let ctx = Ctx(ctx);
        let gate = Gate::new();
        let g = gate.clone();
        let subscriber = s
            .session
            .declare_subscriber(key.clone())
            .callback(move |sample: Sample| {
                g.pass(|| {
                    let k = sample.key_expr().as_str();
                    let payload = sample.payload().to_bytes();
                    let att = zbytes_cow(sample.attachment());
                    let c = ctx;
                    cb(
                        c.0,
                        k.as_ptr() as *const c_char,
                        k.len(),
                        payload.as_ptr(),
                        payload.len(),
                        att.as_ptr(),
                        att.len(),
                    );
                });
            })
            .wait()
            .map_err(|e| format!("cannot declare subscriber on '{key}': {e}"))?;
        Ok(Box::into_raw(Box::new(HrczSubscriber { subscriber, gate })))
    })
}

/// Subscribes to liveliness changes of tokens matching `key_expr`. `history` != 0: tokens that are
/// already alive are reported (alive = 1) right after declaration.
///
/// # Safety
/// Each pointer argument is NULL where the header allows it, or valid for the call:
/// strings NUL-terminated, buffers at least as long as their length argument, handles
/// returned by this library and not yet freed.
#[no_mangle]
pub unsafe extern "C" fn hrcz_declare_liveliness_subscriber(
    session: *const HrczSession,
    key_expr: *const c_char,
    history: c_int,
    callback: HrczLivelinessCallback,
    ctx: *mut c_void,
    err: *mut c_char,
    err_cap: usize,
) -> *mut HrczSubscriber {
    guarded(err, err_cap, std::ptr::null_mut(), || {
        let s = session_ref(session)?;
        let key = cstr(key_expr, "key_expr")?.to_string();
        let cb = callback.ok_or("callback is NULL")?;
        let ctx = Ctx(ctx);
        let gate = Gate::new();
        let g = gate.clone();
        let subscriber = s
            .session
            .liveliness()
            .declare_subscriber(key.clone())
            .history(history != 0)
            .callback(move |sample: Sample| {
                g.pass(|| {
                    let k = sample.key_expr().as_str();
                    let alive = if sample.kind() == SampleKind::Put {
                        1
                    } else {
                        0
                    };
                    let c = ctx;
                    cb(c.0, k.as_ptr() as *const c_char, k.len(), alive);
                });
            })
            .wait()
            .map_err(|e| format!("cannot declare liveliness subscriber on '{key}': {e}"))?;
        Ok(Box::into_raw(Box::new(HrczSubscriber { subscriber, gate })))
    })
}

/// Undeclares and frees a (data or liveliness) subscriber. When it returns, the callback is not
/// running and will never run again. Must not be called from that subscriber's own callback.
/// NULL is a no-op.
///
/// # Safety
/// The handle is NULL or one this library returned and not yet freed; it is invalid
/// afterwards. Not from inside the handle's own callback.
#[no_mangle]
pub unsafe extern "C" fn hrcz_undeclare_subscriber(subscriber: *mut HrczSubscriber) {
    if subscriber.is_null() {
        return;
    }
    let _ = catch_unwind(AssertUnwindSafe(|| {
        let s = Box::from_raw(subscriber);
        s.gate.close();
        let _ = s.subscriber.undeclare().wait();
    }));
}

// ------------------------------------------------------------------ liveliness tokens

/// Opaque liveliness token handle.
pub struct HrczToken {
    token: LivelinessToken,
}

/// Declares a liveliness token on `key` (a concrete key, no wildcards).
///
/// # Safety
/// Each pointer argument is NULL where the header allows it, or valid for the call:
/// strings NUL-terminated, buffers at least as long as their length argument, handles
/// returned by this library and not yet freed.
#[no_mangle]
pub unsafe extern "C" fn hrcz_declare_token(
    session: *const HrczSession,
    key: *const c_char,
    err: *mut c_char,
    err_cap: usize,
) -> *mut HrczToken {
    guarded(err, err_cap, std::ptr::null_mut(), || {
        let s = session_ref(session)?;
        let key = cstr(key, "key")?.to_string();
        let token = s
            .session
            .liveliness()
            .declare_token(key.clone())
            .wait()
            .map_err(|e| format!("cannot declare liveliness token '{key}': {e}"))?;
        Ok(Box::into_raw(Box::new(HrczToken { token })))
    })
}

/// Undeclares and frees a liveliness token. NULL is a no-op.
///
/// # Safety
/// The handle is NULL or one this library returned and not yet freed; it is invalid
/// afterwards.
#[no_mangle]
pub unsafe extern "C" fn hrcz_undeclare_token(token: *mut HrczToken) {
    if token.is_null() {
        return;
    }
    let _ = catch_unwind(AssertUnwindSafe(|| {
        let t = Box::from_raw(token);
        let _ = t.token.undeclare().wait();
    }));
}

// ------------------------------------------------------------------ queryable and get

/// A query being answered; valid only during the query callback.
pub struct HrczQuery<'a> {
    query: &'a Query,
    reply_key: &'a str,
}

/// Query callback: the query's key expression (not NUL-terminated), payload and attachment
/// (empty if none). Reply with `hrcz_query_reply(query, ...)` before returning.
pub type HrczQueryCallback = Option<
    unsafe extern "C" fn(
        ctx: *mut c_void,
        query: *const HrczQuery,
        key: *const c_char,
        key_len: usize,
        payload: *const u8,
        len: usize,
        attachment: *const u8,
        att_len: usize,
    ),
>;

/// Opaque queryable handle.
pub struct HrczQueryable {
    queryable: Queryable<()>,
    gate: Gate,
}

/// Declares a queryable on `key`; replies are sent on `key` itself (so a wildcard query such as
/// `.../stats/*` gets concrete reply keys).
///
/// # Safety
/// Each pointer argument is NULL where the header allows it, or valid for the call:
/// strings NUL-terminated, buffers at least as long as their length argument, handles
/// returned by this library and not yet freed.
#[no_mangle]
pub unsafe extern "C" fn hrcz_declare_queryable(
    session: *const HrczSession,
    key: *const c_char,
    callback: HrczQueryCallback,
    ctx: *mut c_void,
    err: *mut c_char,
    err_cap: usize,
) -> *mut HrczQueryable {
    guarded(err, err_cap, std::ptr::null_mut(), || {
        let s = session_ref(session)?;
        let key = cstr(key, "key")?.to_string();
        let cb = callback.ok_or("callback is NULL")?;
        let ctx = Ctx(ctx);
        let gate = Gate::new();
        let g = gate.clone();
        let reply_key = key.clone();
        let queryable = s
            .session
            .declare_queryable(key.clone())
            .callback(move |query: Query| {
                g.pass(|| {
                    let k = query.key_expr().as_str().to_string();
                    let payload = zbytes_cow(query.payload()).into_owned();
                    let att = zbytes_cow(query.attachment()).into_owned();
                    let q = HrczQuery {
                        query: &query,
                        reply_key: &reply_key,
                    };
                    let c = ctx;
                    cb(
                        c.0,
                        &q as *const HrczQuery,
                        k.as_ptr() as *const c_char,
                        k.len(),
                        payload.as_ptr(),
                        payload.len(),
                        att.as_ptr(),
                        att.len(),
                    );
                });
            })
            .wait()
            .map_err(|e| format!("cannot declare queryable on '{key}': {e}"))?;
        Ok(Box::into_raw(Box::new(HrczQueryable { queryable, gate })))
    })
}

/// Sends one reply to `query` (only inside the query callback). Returns 0 on success, -1 on error.
///
/// # Safety
/// Each pointer argument is NULL where the header allows it, or valid for the call:
/// strings NUL-terminated, buffers at least as long as their length argument, handles
/// returned by this library and not yet freed.
#[no_mangle]
pub unsafe extern "C" fn hrcz_query_reply(
    query: *const HrczQuery,
    payload: *const u8,
    len: usize,
    attachment: *const u8,
    att_len: usize,
    err: *mut c_char,
    err_cap: usize,
) -> c_int {
    guarded(err, err_cap, -1, || {
        let q = query.as_ref().ok_or("query is NULL")?;
        let data = bytes(payload, len, "payload")?;
        let att = bytes(attachment, att_len, "attachment")?;
        let mut reply = q.query.reply(q.reply_key, data.to_vec());
        if !att.is_empty() {
            reply = reply.attachment(att.to_vec());
        }
        reply
            .wait()
            .map_err(|e| format!("reply on '{}' failed: {e}", q.reply_key))?;
        Ok(0)
    })
}

/// Sends an error reply to `query` (only inside the query callback). 0 on success, -1 on error.
///
/// # Safety
/// Each pointer argument is NULL where the header allows it, or valid for the call:
/// strings NUL-terminated, buffers at least as long as their length argument, handles
/// returned by this library and not yet freed.
#[no_mangle]
pub unsafe extern "C" fn hrcz_query_reply_err(
    query: *const HrczQuery,
    payload: *const u8,
    len: usize,
    err: *mut c_char,
    err_cap: usize,
) -> c_int {
    guarded(err, err_cap, -1, || {
        let q = query.as_ref().ok_or("query is NULL")?;
        let data = bytes(payload, len, "payload")?;
        q.query
            .reply_err(data.to_vec())
            .wait()
            .map_err(|e| format!("error reply on '{}' failed: {e}", q.reply_key))?;
        Ok(0)
    })
}

/// Undeclares and frees a queryable; afterwards its callback never runs again. NULL is a no-op.
///
/// # Safety
/// The handle is NULL or one this library returned and not yet freed; it is invalid
/// afterwards. Not from inside the handle's own callback.
#[no_mangle]
pub unsafe extern "C" fn hrcz_undeclare_queryable(queryable: *mut HrczQueryable) {
    if queryable.is_null() {
        return;
    }
    let _ = catch_unwind(AssertUnwindSafe(|| {
        let q = Box::from_raw(queryable);
        q.gate.close();
        let _ = q.queryable.undeclare().wait();
    }));
}

/// Reply callback of `hrcz_get`: is_error = 0 for a normal reply (key = reply key), 1 for an
/// error reply (key empty, payload = error payload).
pub type HrczReplyCallback = Option<
    unsafe extern "C" fn(
        ctx: *mut c_void,
        key: *const c_char,
        key_len: usize,
        payload: *const u8,
        len: usize,
        attachment: *const u8,
        att_len: usize,
        is_error: c_int,
    ),
>;

/// Sends a query on `selector` with an optional payload and attachment, blocks until all replies
/// arrived or `timeout_ms` passed, and calls `callback` on the calling thread for each reply.
/// Returns the number of replies delivered, or -1 on error.
///
/// # Safety
/// Each pointer argument is NULL where the header allows it, or valid for the call:
/// strings NUL-terminated, buffers at least as long as their length argument, handles
/// returned by this library and not yet freed.
#[no_mangle]
pub unsafe extern "C" fn hrcz_get(
    session: *const HrczSession,
    selector: *const c_char,
    payload: *const u8,
    len: usize,
    attachment: *const u8,
    att_len: usize,
    timeout_ms: u64,
    callback: HrczReplyCallback,
    ctx: *mut c_void,
    err: *mut c_char,
    err_cap: usize,
) -> i64 {
    guarded(err, err_cap, -1, || {
        let s = session_ref(session)?;
        let sel = cstr(selector, "selector")?.to_string();
        let data = bytes(payload, len, "payload")?;
        let att = bytes(attachment, att_len, "attachment")?;
        let cb = callback.ok_or("callback is NULL")?;
        let mut get = s
            .session
            .get(sel.clone())
            .timeout(Duration::from_millis(timeout_ms));
        if !data.is_empty() {
            get = get.payload(data.to_vec());
        }
        if !att.is_empty() {
            get = get.attachment(att.to_vec());
        }
        let replies = get.wait().map_err(|e| format!("get '{sel}' failed: {e}"))?;
        let mut n: i64 = 0;
        // The channel closes when the query is finalised (all replies in) or times out.
        while let Ok(reply) = replies.recv() {
            match reply.result() {
                Ok(sample) => {
                    let k = sample.key_expr().as_str();
                    let p = sample.payload().to_bytes();
                    let a = zbytes_cow(sample.attachment());
                    cb(
                        ctx,
                        k.as_ptr() as *const c_char,
                        k.len(),
                        p.as_ptr(),
                        p.len(),
                        a.as_ptr(),
                        a.len(),
                        0,
                    );
                }
                Err(e) => {
                    let p = e.payload().to_bytes();
                    cb(
                        ctx,
                        "".as_ptr() as *const c_char,
                        0,
                        p.as_ptr(),
                        p.len(),
                        std::ptr::null(),
                        0,
                        1,
                    );
                }
            }
            n += 1;
        }
        Ok(n)
    })
}

// ------------------------------------------------------------------ key expressions

/// 1 if the key expressions `a` and `b` intersect (share at least one key), 0 if not, -1 if either
/// is not a valid canonical key expression (error text in `err`).
///
/// # Safety
/// Each pointer argument is NULL where the header allows it, or valid for the call:
/// strings NUL-terminated, buffers at least as long as their length argument, handles
/// returned by this library and not yet freed.
#[no_mangle]
pub unsafe extern "C" fn hrcz_keyexpr_intersects(
    a: *const c_char,
    b: *const c_char,
    err: *mut c_char,
    err_cap: usize,
) -> c_int {
    guarded(err, err_cap, -1, || {
        let a_s = cstr(a, "a")?;
        let b_s = cstr(b, "b")?;
        let ka = zenoh::key_expr::keyexpr::new(a_s)
            .map_err(|e| format!("invalid key expression '{a_s}': {e}"))?;
        let kb = zenoh::key_expr::keyexpr::new(b_s)
            .map_err(|e| format!("invalid key expression '{b_s}': {e}"))?;
        Ok(if ka.intersects(kb) { 1 } else { 0 })
    })
}

#[cfg(test)]
mod tests;
