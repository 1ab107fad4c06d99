//! Unit tests of the C ABI (lib.rs).
use super::*;
use std::ffi::CString;

#[test]
fn bad_config_gives_error_text() {
    let mut buf = [0 as c_char; 256];
    let cfg = CString::new("{ mode: 42 ").unwrap();
    let s = unsafe { hrcz_open(cfg.as_ptr(), buf.as_mut_ptr(), buf.len()) };
    assert!(s.is_null());
    let msg = unsafe { CStr::from_ptr(buf.as_ptr()) }.to_str().unwrap();
    assert!(msg.contains("invalid zenoh config"), "{msg}");
}

#[test]
fn keyexpr_intersection() {
    let a = CString::new("hrc/s/robot/*/command").unwrap();
    let b = CString::new("hrc/s/robot/r1/command").unwrap();
    let c = CString::new("hrc/s/robot/r1/state").unwrap();
    let bad = CString::new("hrc//x").unwrap();
    let mut buf = [0 as c_char; 128];
    unsafe {
        assert_eq!(
            hrcz_keyexpr_intersects(a.as_ptr(), b.as_ptr(), buf.as_mut_ptr(), buf.len()),
            1
        );
        assert_eq!(
            hrcz_keyexpr_intersects(a.as_ptr(), c.as_ptr(), buf.as_mut_ptr(), buf.len()),
            0
        );
        assert_eq!(
            hrcz_keyexpr_intersects(a.as_ptr(), bad.as_ptr(), buf.as_mut_ptr(), buf.len()),
            -1
        );
    }
}

#[test]
fn open_ex_names_the_bad_path() {
    let paths = [CString::new("mode").unwrap()];
    let values = [CString::new("\"nonsense\"").unwrap()];
    let pp: Vec<*const c_char> = paths.iter().map(|p| p.as_ptr()).collect();
    let vv: Vec<*const c_char> = values.iter().map(|p| p.as_ptr()).collect();
    let mut buf = [0 as c_char; 512];
    let s = unsafe {
        hrcz_open_ex(
            std::ptr::null(),
            pp.as_ptr(),
            vv.as_ptr(),
            1,
            buf.as_mut_ptr(),
            buf.len(),
        )
    };
    assert!(s.is_null());
    let msg = unsafe { CStr::from_ptr(buf.as_ptr()) }.to_str().unwrap();
    assert!(msg.contains("'mode'"), "{msg}");
}

#[test]
fn null_arguments_are_errors_not_crashes() {
    let mut buf = [0 as c_char; 128];
    let p = unsafe {
        hrcz_declare_publisher(
            std::ptr::null(),
            std::ptr::null(),
            1,
            1,
            buf.as_mut_ptr(),
            buf.len(),
        )
    };
    assert!(p.is_null());
    let msg = unsafe { CStr::from_ptr(buf.as_ptr()) }.to_str().unwrap();
    assert_eq!(msg, "session is NULL");
    unsafe {
        hrcz_close(std::ptr::null_mut());
        hrcz_undeclare_publisher(std::ptr::null_mut());
        hrcz_undeclare_subscriber(std::ptr::null_mut());
        hrcz_undeclare_token(std::ptr::null_mut());
        hrcz_undeclare_queryable(std::ptr::null_mut());
    }
}
