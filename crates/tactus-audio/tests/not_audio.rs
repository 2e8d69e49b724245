//! A text file given as a song says it is not audio, whatever the decoder library finds in
//! it: Symphonia's probe scans the whole stream for container markers, so a text that
//! mentions `ID3` was reported as "audio codec not supported (id3v2: unsupported ID3v2
//! version)", and one with other marker-like bytes as a truncated file. Audio and binary
//! garbage keep their own errors.

use std::path::{Path, PathBuf};

use tactus_audio::source::{decode_all, AudioSource, SourceError};

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
}

#[test]
fn a_text_file_is_not_audio() {
    let dir = tempfile::tempdir().unwrap();
    let texts: [(&str, &[u8]); 5] = [
        ("note.txt", b"hello, this is not a song\n"),
        // A marker the probe finds inside the text: the message must not be about it.
        (
            "tags.mp3",
            b"Notes on tagging\n\nAn MP3 file may start with an ID3 tag (ID3v2.4).\n",
        ),
        (
            "riff.wav",
            b"RIFF and WAVE are the words a WAV file starts with.\r\n",
        ),
        ("chanson.flac", "Café — une chanson ♪\tfin\n".as_bytes()),
        // A multi-byte character cut off by the end of the file.
        ("cut.ogg", &"OggS, then é".as_bytes()[..13]),
    ];
    for (name, bytes) in texts {
        let p = write(dir.path(), name, bytes);
        let e = AudioSource::open(&p).expect_err(name);
        assert!(matches!(e, SourceError::NotAudio(_)), "{name}: {e:?}");
        let msg = e.to_string();
        assert_eq!(
            msg,
            format!(
                "{}: not an audio file (no known audio format found; the file is text)",
                p.display()
            )
        );
        assert!(!msg.contains("ID3"), "{msg}");
        assert!(matches!(decode_all(&p), Err(SourceError::NotAudio(_))));
    }
}

#[test]
fn binary_garbage_and_audio_are_not_called_text() {
    let dir = tempfile::tempdir().unwrap();
    // Text with a NUL byte, and bytes that are not UTF-8: binary, as before.
    for (name, bytes) in [
        ("nul.mp3", &b"hello\0world, not audio either\n"[..]),
        ("latin1.wav", &b"caf\xe9 au lait, not audio\n"[..]),
    ] {
        let p = write(dir.path(), name, bytes);
        let e = AudioSource::open(&p).expect_err(name);
        assert!(
            matches!(e, SourceError::UnsupportedFormat { .. }),
            "{name}: {e:?}"
        );
    }
    // A real song still opens.
    let d = decode_all(&fixture("mp3_44100_stereo.mp3")).unwrap();
    assert!(!d.left.is_empty());
}
