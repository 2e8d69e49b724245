//! write_atomic: replaces on success; on failure leaves the old file and no temp file.

use std::fs;
use std::io;
use std::path::Path;

use tactus_glove::write_atomic;

fn entries(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn success_creates_and_replaces() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("out.json");
    write_atomic(&path, |w| w.write_all(b"first")).unwrap();
    assert_eq!(fs::read(&path).unwrap(), b"first");
    write_atomic(&path, |w| w.write_all(b"second, longer")).unwrap();
    assert_eq!(fs::read(&path).unwrap(), b"second, longer");
    assert_eq!(entries(dir.path()), vec!["out.json"]);
}

#[test]
fn failing_writer_leaves_old_file_and_no_temp() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("pattern.json");
    fs::write(&path, b"old content").unwrap();
    let err = write_atomic(&path, |w| {
        w.write_all(&[b'x'; 100_000])?; // more than the buffer: bytes reach the temp file
        Err(io::Error::other("boom"))
    })
    .unwrap_err();
    assert_eq!(err.to_string(), "boom");
    assert_eq!(fs::read(&path).unwrap(), b"old content");
    assert_eq!(entries(dir.path()), vec!["pattern.json"]);

    // Same without an existing target: nothing is left at all.
    let fresh = dir.path().join("fresh.json");
    assert!(write_atomic(&fresh, |_| Err(io::Error::other("nope"))).is_err());
    assert_eq!(entries(dir.path()), vec!["pattern.json"]);
}

#[test]
fn missing_or_unwritable_directory_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("no/such/dir/out.json");
    assert!(write_atomic(&missing, |w| w.write_all(b"x")).is_err());

    // A target that is a directory cannot be replaced by a file: rename fails, temp removed.
    let sub = dir.path().join("sub");
    fs::create_dir(&sub).unwrap();
    fs::write(sub.join("keep"), b"k").unwrap();
    assert!(write_atomic(&sub, |w| w.write_all(b"x")).is_err());
    assert_eq!(entries(dir.path()), vec!["sub"]);

    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let ro = dir.path().join("ro");
        fs::create_dir(&ro).unwrap();
        fs::set_permissions(&ro, fs::Permissions::from_mode(0o555)).unwrap();
        let target = ro.join("out.json");
        let result = write_atomic(&target, |w| w.write_all(b"x"));
        // root ignores directory permissions; only assert where they are enforced.
        let probe = fs::write(ro.join("probe"), b"p");
        if probe.is_err() {
            assert!(result.is_err());
            assert!(!target.exists());
        }
        fs::set_permissions(&ro, fs::Permissions::from_mode(0o755)).unwrap();
    }
}

/// /proc refuses new files even for root, so this runs the "unwritable directory" path
/// whoever runs the tests.
#[cfg(target_os = "linux")]
#[test]
fn proc_is_unwritable() {
    let target = Path::new("/proc/tactus-glove-atomic-test.json");
    assert!(write_atomic(target, |w| w.write_all(b"x")).is_err());
    assert!(!target.exists());
}

#[test]
fn no_file_name_is_an_error() {
    assert!(write_atomic(Path::new("/"), |w| w.write_all(b"x")).is_err());
}

#[cfg(unix)]
#[test]
fn keeps_permissions_of_replaced_file() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("p");
    fs::write(&path, b"a").unwrap();
    fs::set_permissions(&path, fs::Permissions::from_mode(0o640)).unwrap();
    write_atomic(&path, |w| w.write_all(b"b")).unwrap();
    assert_eq!(
        fs::metadata(&path).unwrap().permissions().mode() & 0o777,
        0o640
    );
}

#[test]
fn output_set_is_all_or_nothing() {
    use tactus_glove::{OutputError, OutputSet};
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a.json"), dir.path().join("b.json"));
    fs::write(&a, b"old").unwrap();
    {
        let mut set =
            OutputSet::prepare(&[("-o", a.as_path()), ("--features", b.as_path())], &[]).unwrap();
        assert_eq!(
            entries(dir.path()).len(),
            3,
            "two temporaries next to a.json"
        );
        set.write(0, b"new").unwrap();
        // Dropped before commit: the temporaries go, the old file stays.
    }
    assert_eq!(entries(dir.path()), vec!["a.json"]);
    assert_eq!(fs::read(&a).unwrap(), b"old");
    // An output that is an input, or named twice, is refused before anything is created.
    let e = OutputSet::prepare(&[("-o", a.as_path())], &[a.as_path()])
        .err()
        .unwrap();
    assert!(matches!(e, OutputError::IsInput { .. }), "{e}");
    let e = OutputSet::prepare(&[("-o", b.as_path()), ("--plot", b.as_path())], &[])
        .err()
        .unwrap();
    assert!(matches!(e, OutputError::Duplicate { .. }), "{e}");
    assert_eq!(entries(dir.path()), vec!["a.json"]);
    let mut set =
        OutputSet::prepare(&[("-o", a.as_path()), ("--features", b.as_path())], &[]).unwrap();
    set.write(0, b"A").unwrap();
    set.write(1, b"B").unwrap();
    set.commit().unwrap();
    assert_eq!(fs::read(&a).unwrap(), b"A");
    assert_eq!(fs::read(&b).unwrap(), b"B");
    assert_eq!(entries(dir.path()), vec!["a.json", "b.json"]);
}
