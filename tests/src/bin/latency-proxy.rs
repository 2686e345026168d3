//! A proxy that adds a round-trip time to every request to a local server
//! (this machine's kernel has no `netem`), and optionally sends the answers
//! through a link of a given rate shared by all connections:
//! `latency-proxy LISTEN_PORT SERVER_PORT RTT_MS [MBIT_PER_S]`. For
//! measuring remote walks:
//!
//!   bash scripts/serve.sh DIR 8080 &
//!   latency-proxy 8050 8080 50 100 &
//!   hlod-bench http://127.0.0.1:8050/plant.hlod …

use std::time::Duration;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let number = |s: &str| s.parse::<f64>().ok().filter(|r| r.is_finite() && *r >= 0.0);
    let parsed = match args.as_slice() {
        [_, listen, server, rtt, rest @ ..] if rest.len() <= 1 => {
            let mbit = match rest {
                [m] => number(m).filter(|&m| m > 0.0).map(Some),
                _ => Some(None),
            };
            listen
                .parse::<u16>()
                .ok()
                .zip(server.parse::<u16>().ok())
                .zip(number(rtt))
                .zip(mbit)
        }
        _ => None,
    };
    let Some((((listen, server), rtt), mbit)) = parsed else {
        eprintln!("usage: latency-proxy LISTEN_PORT SERVER_PORT RTT_MS [MBIT_PER_S]");
        std::process::exit(2);
    };
    let p = e2e_tests::servers::FaultProxy::start_link(
        listen,
        server,
        Duration::from_secs_f64(rtt / 1e3),
        mbit.map(|m| m * 1e6 / 8.0),
    );
    let rate = mbit.map_or("no rate cap".to_string(), |m| format!("{m} Mbit/s"));
    println!(
        "latency-proxy: {} -> 127.0.0.1:{server}, {rtt} ms per request, {rate}",
        p.base
    );
    loop {
        std::thread::park();
    }
}
