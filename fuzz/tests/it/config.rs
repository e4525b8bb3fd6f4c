//! Fuzzes the daemon configuration: `RawConfig::parse` then `Config::validate`, alone and
//! overlaid on the embedded default (what `frondd --config FILE` does).

use frond_fuzz::{Target, as_text, assert_message, fuzz};
use frondd::config::{Config, DEFAULT_CONFIG, RawConfig};

#[test]
fn fuzz_daemon_config() {
    let seeds = [
        DEFAULT_CONFIG,
        "[publisher]\nqueue_frames = 64\nwrite_timeout_ms = 1500\n",
        "tick_rate_hz = 500\nrig = \"/etc/frond/rigs/fern.toml\"\nfilter = \"lowpass:cutoff_hz=8\"\n\
         [source]\nkind = \"replay\"\nreplay = \"hand.jsonl\"\n",
    ];
    for s in seeds {
        let raw = RawConfig::parse(s, "seed").expect("seed configs parse");
        Config::validate(raw).expect("seed configs validate");
    }
    let dict = [
        "tick_rate_hz",
        "rig",
        "calibration",
        "filter",
        "[source]",
        "kind",
        "profile",
        "path",
        "replay",
        "stall_ms",
        "virtual_rate_hz",
        "[publisher]",
        "queue_frames",
        "max_subscribers",
        "write_timeout_ms",
        "[recorder]",
        "fsync_interval_ms",
        "[realtime]",
        "priority",
        "lock_memory",
        "[control]",
        "allowed_uids",
        "allowed_gids",
        "\"auto\"",
        "\"virtual\"",
        "\"in-process\"",
        "\"hid\"",
        "\"replay\"",
        "[0, 1000, -1]",
        "[[hands]]",
        "name",
        "element",
        "\"leaf\"",
        "\"osc://127.0.0.1:9001\"",
    ];
    let report = fuzz(Target::new("daemon-config").seeds(seeds).text().dict(dict), |b| {
        let text = as_text(b);
        match RawConfig::parse(&text, "fuzz.toml") {
            Ok(raw) => {
                let label = match Config::validate(raw) {
                    Ok(_) => "ok",
                    Err(errors) => {
                        assert!(!errors.problems.is_empty(), "refused without a reason");
                        errors.problems.iter().for_each(assert_message);
                        "invalid"
                    }
                };
                let base = RawConfig::parse(DEFAULT_CONFIG, "default").expect("default parses");
                let overlaid =
                    base.overlay(RawConfig::parse(&text, "fuzz.toml").expect("parsed once already"));
                if let Err(errors) = Config::validate(overlaid) {
                    assert!(!errors.problems.is_empty(), "refused without a reason");
                }
                label
            }
            Err(e) => {
                let e = e.to_string();
                assert!(e.starts_with("fuzz.toml"), "the error does not name the file: {e}");
                assert_message(&e);
                "toml"
            }
        }
    });
    report.assert_reaches("ok", 50);
    report.assert_reaches("invalid", 20);
}
