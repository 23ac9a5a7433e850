//! The live view (docs/live.md) in a real browser: headless Chromium, driven through
//! WebDriver, watches simulated acquisitions served by `gonio acquire --serve`,
//! stops one through the page (refused without the token), and shows a finished run
//! served by `gonio view`. Screenshots go to `target/artifacts/`.
//!
//! Needs Chromium and chromedriver: `scripts/browsers` installs them (and
//! `scripts/test` runs it); without them these tests fail, naming the script.

use crate::common;
use crate::common::browser;
use crate::common::live;

use std::time::{Duration, Instant};

use browser::{Browser, run};
use common::{ok, ok_json, scratch, stderr};
use live::{PLAN_STEPS, Served, acquire_args, sim_and_plan};

/// The run file's status and steps done, as `gonio show --json` reads them.
fn show(out: &std::path::Path) -> (String, u64) {
    let v = ok_json(&["show", &out.display().to_string(), "--json"]);
    (
        v["status"].as_str().expect("status").to_string(),
        v["states"]["done"].as_u64().unwrap_or(0),
    )
}

/// The harness itself, on a page of known content: it reads the elements the tests
/// rely on, as the browser rendered them (a hidden link is not visible).
#[test]
fn harness_reads_what_the_browser_rendered() {
    run(async {
        let browser = Browser::open().await;
        browser
            .goto(
                "data:text/html,<p id=status> running </p><b id=done>17</b><b id=total>54</b>\
                 <svg id=brdf><circle class=pt r=1 /><circle class=pt r=1 /><circle r=1 />\
                 </svg><b id=brdf-count>2</b><a id=report-link href=/report.html hidden>r</a>\
                 <button id=stop>Stop</button>",
            )
            .await;
        let p = browser.page().await.expect("the page");
        assert!(p.is("running"), "{p:?}");
        assert_eq!(
            (p.done(), p.total(), p.brdf_count()),
            (Some(17), Some(54), Some(2))
        );
        assert_eq!(p.circles, 2);
        assert!(!p.report_visible && p.stop_visible, "{p:?}");
        assert_eq!(p.control_msg, None);
        let shot = browser.screenshot("harness.png").await;
        assert!(std::fs::metadata(&shot).expect("saved").len() > 1000);
        browser.close().await;
    });
}

/// The page follows a run from its first steps to its end: the steps done and the
/// BRDF's samples grow while it runs, then the page says `complete` and links the
/// report, which opens. The server keeps serving the final state until SIGTERM, then
/// exits with the session's status, 0.
#[test]
fn page_follows_a_run_to_its_end() {
    run(async {
        let t0 = Instant::now();
        let dir = scratch("live-follow");
        // About 16 s of wall time.
        let (sim, plan) = sim_and_plan(&dir, 0.04);
        let out = dir.join("run.gonio");
        let browser = Browser::open().await;
        let mut args = acquire_args(&sim, &plan, &out);
        args.extend(["--serve".into(), "127.0.0.1:0".into()]);
        let served = Served::start(&args, false);
        assert!(served.token.is_none(), "a token without --control");
        browser.goto(&served.url).await;

        let first = browser
            .wait_for("status running", |p| p.is("running") && p.done().is_some())
            .await;
        assert_eq!(first.total(), Some(PLAN_STEPS), "{first:?}");
        let (done0, count0, circles0) = (
            first.done().expect("done"),
            first.brdf_count().unwrap_or(0),
            first.circles,
        );
        assert!(done0 < PLAN_STEPS, "{first:?}");
        let grown = browser
            .wait_for("the steps and the BRDF to grow", |p| {
                p.is("running")
                    && p.done().is_some_and(|d| d > done0)
                    && p.brdf_count().is_some_and(|c| c > count0)
                    && p.circles > circles0
            })
            .await;
        // One circle per sample drawn.
        assert_eq!(Some(grown.circles), grown.brdf_count(), "{grown:?}");
        // Two thirds in, the plots are well filled: the screenshot to look at.
        let grown = browser
            .wait_for("two thirds of the steps", |p| {
                p.is("running") && p.done().is_some_and(|d| d >= PLAN_STEPS * 2 / 3)
            })
            .await;
        assert!(grown.brdf_count().is_some_and(|c| c > count0), "{grown:?}");
        let shot = browser.screenshot("live-view-running.png").await;
        eprintln!(
            "running: {grown:?} ({:.1} s); screenshot {}",
            t0.elapsed().as_secs_f64(),
            shot.display()
        );

        let end = browser
            .wait_for("status complete and the report link", |p| {
                p.is("complete") && p.report_visible
            })
            .await;
        assert_eq!(end.done(), Some(PLAN_STEPS), "{end:?}");
        assert_eq!(end.total(), Some(PLAN_STEPS), "{end:?}");
        assert!(end.brdf_count().is_some_and(|c| c > 0), "{end:?}");
        assert_eq!(Some(end.circles), end.brdf_count(), "{end:?}");
        browser.screenshot("live-view-complete.png").await;
        let href = end.report_href.clone().expect("an href");
        assert_eq!(href, format!("{}report.html", served.url), "{end:?}");
        browser.goto(&href).await;
        let title = browser.title().await;
        assert!(title.contains("Gonio run report"), "title {title:?}");
        browser.close().await;

        // Still serving the final state: it ends on SIGTERM with the session's status.
        let (status, err) = served.terminate();
        assert_eq!(status.code(), Some(0), "{err}");
        assert_eq!(show(&out), ("complete".to_string(), PLAN_STEPS));
        eprintln!(
            "page_follows_a_run_to_its_end: {:.1} s",
            t0.elapsed().as_secs_f64()
        );
    });
}

/// With `--control`, Stop works only with the token of the terminal's URL: the page
/// opened without it is refused and the run goes on; with it, the run ends
/// `interrupted` (exit 130 on SIGTERM) and `gonio resume` completes it.
#[test]
fn stop_needs_the_token_and_leaves_a_resumable_run() {
    run(async {
        let t0 = Instant::now();
        let dir = scratch("live-stop");
        // About 30 s of wall time, if nothing stopped it.
        let (sim, plan) = sim_and_plan(&dir, 0.08);
        let out = dir.join("run.gonio");
        let browser = Browser::open().await;
        let mut args = acquire_args(&sim, &plan, &out);
        args.extend(["--serve".into(), "127.0.0.1:0".into(), "--control".into()]);
        let served = Served::start(&args, true);
        let token = served.token.clone().expect("a token");
        // 128 bits, in hex or base64url: at least 22 characters.
        assert!(token.len() >= 22, "token {token:?}");

        // Without the token: Stop is refused and the run goes on.
        browser.goto(&served.url).await;
        browser
            .wait_for("status running, Stop shown", |p| {
                p.is("running") && p.done().is_some() && p.stop_visible
            })
            .await;
        browser.click("#stop").await;
        browser.click("#stop").await;
        let refused = browser
            .wait_for("Stop refused", |p| {
                p.control_msg.as_deref().is_some_and(|m| {
                    let m = m.to_lowercase();
                    m.contains("refused") || m.contains("token")
                })
            })
            .await;
        assert!(refused.is("running"), "{refused:?}");
        let done = refused.done().expect("done");
        browser
            .wait_for("the run to go on after the refusal", |p| {
                p.is("running") && p.done().is_some_and(|d| d > done)
            })
            .await;
        browser.screenshot("live-view-stop-refused.png").await;

        // With the token: the run stops, interrupted.
        browser.goto(&served.token_url()).await;
        browser
            .wait_for("status running, Stop shown (with the token)", |p| {
                p.is("running") && p.stop_visible
            })
            .await;
        browser.click("#stop").await;
        browser.click("#stop").await;
        let stopped = browser
            .wait_for("status interrupted", |p| p.is("interrupted"))
            .await;
        let stopped_at = stopped.done().expect("done");
        assert!(stopped_at < PLAN_STEPS, "{stopped:?}");
        browser.screenshot("live-view-interrupted.png").await;
        browser.close().await;

        let (status, err) = served.terminate();
        assert_eq!(status.code(), Some(130), "{err}");
        let (state, done) = show(&out);
        assert_eq!(state, "interrupted");
        assert!(done < PLAN_STEPS, "{done} of {PLAN_STEPS} done");

        // The run resumes to its end, every step done.
        let o = ok(&["resume", &out.display().to_string()]);
        assert!(stderr(&o).contains("complete"), "{}", stderr(&o));
        assert_eq!(show(&out), ("complete".to_string(), PLAN_STEPS));
        eprintln!(
            "stop_needs_the_token_and_leaves_a_resumable_run: stopped at {stopped_at}, {:.1} s",
            t0.elapsed().as_secs_f64()
        );
    });
}

/// `gonio view` serves a finished run read-only: the page shows it complete with
/// every step, its BRDF and the report link, and Stop answers 403.
#[test]
fn view_serves_a_finished_run() {
    run(async {
        let t0 = Instant::now();
        let dir = scratch("live-view");
        let (sim, plan) = sim_and_plan(&dir, 0.0);
        let out = dir.join("run.gonio");
        let o = ok(&acquire_args(&sim, &plan, &out)
            .iter()
            .map(String::as_str)
            .collect::<Vec<_>>());
        assert!(stderr(&o).contains("complete"), "{}", stderr(&o));
        let browser = Browser::open().await;
        let served = Served::start(
            &[
                "view".into(),
                out.display().to_string(),
                "--serve".into(),
                "127.0.0.1:0".into(),
            ],
            false,
        );
        browser.goto(&served.url).await;
        let p = browser
            .wait_for("status complete and the report link", |p| {
                p.is("complete") && p.report_visible && p.brdf_count().is_some()
            })
            .await;
        assert_eq!(p.done(), Some(PLAN_STEPS), "{p:?}");
        assert_eq!(p.total(), Some(PLAN_STEPS), "{p:?}");
        assert!(p.brdf_count().is_some_and(|c| c > 0), "{p:?}");
        assert_eq!(Some(p.circles), p.brdf_count(), "{p:?}");
        assert!(!p.stop_visible, "Stop shown by `gonio view`: {p:?}");
        browser.screenshot("live-view-finished.png").await;
        let (code, body) = browser.fetch("POST", "/control/stop").await;
        assert_eq!(code, 403, "{body}");
        // Nothing changed.
        tokio::time::sleep(Duration::from_millis(500)).await;
        assert!(browser.page().await.expect("the page").is("complete"));
        browser.close().await;

        let (status, err) = served.terminate();
        assert_eq!(status.code(), Some(0), "{err}");
        assert_eq!(show(&out), ("complete".to_string(), PLAN_STEPS));
        eprintln!(
            "view_serves_a_finished_run: {:.1} s",
            t0.elapsed().as_secs_f64()
        );
    });
}
