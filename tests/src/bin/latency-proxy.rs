//! A proxy that adds a round-trip time to every request to a local server
//! (this machine's kernel has no `netem`): `latency-proxy LISTEN_PORT
//! SERVER_PORT RTT_MS`. For measuring remote walks:
//!
//!   bash scripts/serve.sh DIR 8080 &
//!   latency-proxy 8050 8080 50 &
//!   hlod-bench http://127.0.0.1:8050/plant.hlod …

use std::time::Duration;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let parsed = match args.as_slice() {
        [_, listen, server, rtt] => listen
            .parse::<u16>()
            .ok()
            .zip(server.parse::<u16>().ok())
            .zip(
                rtt.parse::<f64>()
                    .ok()
                    .filter(|r| r.is_finite() && *r >= 0.0),
            ),
        _ => None,
    };
    let Some(((listen, server), rtt)) = parsed else {
        eprintln!("usage: latency-proxy LISTEN_PORT SERVER_PORT RTT_MS");
        std::process::exit(2);
    };
    let p = e2e_tests::servers::FaultProxy::start_on(
        listen,
        server,
        Duration::from_secs_f64(rtt / 1e3),
    );
    println!(
        "latency-proxy: {} -> 127.0.0.1:{server}, {rtt} ms per request",
        p.base
    );
    loop {
        std::thread::park();
    }
}
