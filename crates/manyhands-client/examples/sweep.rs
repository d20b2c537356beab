//! A controller's view of the server: submit a `collision_sweep` job, follow its events, print
//! the result; then show an API error naming the offending field.
//!
//! `cargo run -p manyhands-client --example sweep -- http://127.0.0.1:8080 [TOKEN]`

use std::time::Duration;

use manyhands_client::api::{CollisionSweep, FkRequest, PlanRequest};
use manyhands_client::{Client, ClientError};

#[tokio::main(flavor = "current_thread")]
async fn main() -> Result<(), ClientError> {
    let mut args = std::env::args().skip(1);
    let url = args
        .next()
        .unwrap_or_else(|| "http://127.0.0.1:8080".into());
    let mut c = Client::new(&url)?;
    if let Some(token) = args.next() {
        c = c.with_token(token);
    }
    println!("server {}", c.health().await?.version);

    let request = PlanRequest::CollisionSweep(CollisionSweep {
        scene: "kitchen".into(),
        robots: None,
        samples: 20_000,
        seed: Some(1),
        time_limit: Some(5.0),
        priority: None,
        max_attempts: None,
    });
    let job = c.submit(&request, None).await?;
    c.events(&job.id, |ev| println!("{}: {}", ev.event, ev.data))
        .await?;
    let done = c.wait(&job.id, Duration::from_secs(30)).await?;
    println!("{} {}", done.state.name(), done.result.unwrap_or_default());

    let bad = FkRequest {
        robot: "armar".into(),
        named: None,
        config: [("right_elbow".to_string(), 4.2)].into(),
        links: None,
    };
    match c.fk(&bad).await {
        Err(e @ ClientError::Api { .. }) => {
            println!("refused: {e} (field {})", e.field().unwrap_or("none"))
        }
        other => println!("unexpected: {other:?}"),
    }
    Ok(())
}
