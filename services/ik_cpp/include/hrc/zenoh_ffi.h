/*
 * C ABI of the Rust crate hrc_zenoh_ffi (services/ik_cpp/zenoh_ffi/src/lib.rs) over zenoh 1.10.2.
 * Hand-written: keep it in sync with lib.rs.
 *
 * Contract:
 * - hrcz_open / hrcz_declare_* return an owned handle or NULL. On NULL (and on a -1 return of the
 *   other functions) a NUL-terminated error text is written to `err` (capacity `err_cap`, may be
 *   NULL). Every handle is freed by exactly one call of its free function; all accept NULL.
 * - No Rust panic crosses this boundary. Callbacks must not throw (C++ callers catch everything).
 * - Callbacks run on zenoh threads. The callbacks of one subscriber or queryable never run
 *   concurrently, and after hrcz_undeclare_subscriber / hrcz_undeclare_queryable returns they never
 *   run again. Never undeclare a handle from inside its own callback (deadlock).
 * - Free entities (publishers, subscribers, tokens, queryables) before closing their session.
 * - Keys passed to callbacks are NOT NUL-terminated: use key_len. Pointers passed to callbacks are
 *   valid only during the call.
 */
#ifndef HRC_ZENOH_FFI_H
#define HRC_ZENOH_FFI_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct HrczSession HrczSession;
typedef struct HrczPublisher HrczPublisher;
typedef struct HrczSubscriber HrczSubscriber;
typedef struct HrczToken HrczToken;
typedef struct HrczQueryable HrczQueryable;
typedef struct HrczQuery HrczQuery;

typedef void (*HrczSampleCallback)(void* ctx, const char* key, size_t key_len,
                                   const uint8_t* payload, size_t len, const uint8_t* attachment,
                                   size_t att_len);
/* alive: 1 = token appeared (or already existed, with history), 0 = token dropped. */
typedef void (*HrczLivelinessCallback)(void* ctx, const char* key, size_t key_len, int alive);
/* Reply with hrcz_query_reply(query, ...) before returning; `query` is invalid afterwards. */
typedef void (*HrczQueryCallback)(void* ctx, const HrczQuery* query, const char* key,
                                  size_t key_len, const uint8_t* payload, size_t len,
                                  const uint8_t* attachment, size_t att_len);
/* is_error: 0 = normal reply (key = reply key), 1 = error reply (key empty). */
typedef void (*HrczReplyCallback)(void* ctx, const char* key, size_t key_len,
                                  const uint8_t* payload, size_t len, const uint8_t* attachment,
                                  size_t att_len, int is_error);

/* ---- session */
HrczSession* hrcz_open(const char* config_json5, char* err, size_t err_cap);
/* Like the Python services: start from the zenoh config file base_file (NULL or "" = defaults),
 * then insert values_json5[i] at paths[i] for i < n (e.g. "mode" = "\"peer\""). */
HrczSession* hrcz_open_ex(const char* base_file, const char* const* paths,
                          const char* const* values_json5, size_t n, char* err, size_t err_cap);
void hrcz_close(HrczSession* session);

/* ---- publisher. congestion_block != 0: block instead of drop when queues are full;
 *      express != 0: send at once, without batching. */
HrczPublisher* hrcz_declare_publisher(const HrczSession* session, const char* key,
                                      int congestion_block, int express, char* err, size_t err_cap);
/* Returns 0 on success, -1 on error. attachment may be NULL with att_len 0. */
int hrcz_publisher_put(const HrczPublisher* publisher, const uint8_t* payload, size_t len,
                       const uint8_t* attachment, size_t att_len, char* err, size_t err_cap);
/* 1: some subscriber matches the publisher's key now, 0: none, -1: error. */
int hrcz_publisher_has_subscribers(const HrczPublisher* publisher, char* err, size_t err_cap);
void hrcz_undeclare_publisher(HrczPublisher* publisher);

/* ---- subscribers (data and liveliness share one handle type and one free function) */
HrczSubscriber* hrcz_declare_subscriber(const HrczSession* session, const char* key_expr,
                                        HrczSampleCallback callback, void* ctx, char* err,
                                        size_t err_cap);
/* history != 0: tokens already alive are reported (alive = 1) right after declaration. */
HrczSubscriber* hrcz_declare_liveliness_subscriber(const HrczSession* session, const char* key_expr,
                                                   int history, HrczLivelinessCallback callback,
                                                   void* ctx, char* err, size_t err_cap);
void hrcz_undeclare_subscriber(HrczSubscriber* subscriber);

/* ---- liveliness tokens */
HrczToken* hrcz_declare_token(const HrczSession* session, const char* key, char* err,
                              size_t err_cap);
void hrcz_undeclare_token(HrczToken* token);

/* ---- queryable (replies are sent on the queryable's own key) and get */
HrczQueryable* hrcz_declare_queryable(const HrczSession* session, const char* key,
                                      HrczQueryCallback callback, void* ctx, char* err,
                                      size_t err_cap);
int hrcz_query_reply(const HrczQuery* query, const uint8_t* payload, size_t len,
                     const uint8_t* attachment, size_t att_len, char* err, size_t err_cap);
/* An error reply (the querier sees is_error = 1). */
int hrcz_query_reply_err(const HrczQuery* query, const uint8_t* payload, size_t len, char* err,
                         size_t err_cap);
void hrcz_undeclare_queryable(HrczQueryable* queryable);
/* Blocks until every reply arrived or timeout_ms passed; calls `callback` on the calling thread per
 * reply. Returns the number of replies, or -1 on error. */
int64_t hrcz_get(const HrczSession* session, const char* selector, const uint8_t* payload,
                 size_t len, const uint8_t* attachment, size_t att_len, uint64_t timeout_ms,
                 HrczReplyCallback callback, void* ctx, char* err, size_t err_cap);

/* ---- key expressions: 1 if a and b intersect, 0 if not, -1 if either is invalid. */
int hrcz_keyexpr_intersects(const char* a, const char* b, char* err, size_t err_cap);

#ifdef __cplusplus
} /* extern "C" */
#endif

#endif /* HRC_ZENOH_FFI_H */
