//! The LISTEN connection: notices of every replica's writes, forwarded to this store's
//! subscribers; reconnects when lost and then announces [`Notice::Resync`].

#[allow(unused_imports)]
use super::*;

// ---------------------------------------------------------------------------------------------
// LISTEN

type Messages =
    Pin<Box<dyn Stream<Item = Result<AsyncMessage, tokio_postgres::Error>> + Send + 'static>>;

/// The listening connection: its client (kept: dropping it closes the connection) and the
/// connection's messages (polling them drives the connection).
pub(super) struct Listener {
    _client: tokio_postgres::Client,
    messages: Messages,
    /// Notifications that came while `LISTEN` was being sent.
    early: Vec<tokio_postgres::Notification>,
}

pub(super) async fn listen(cfg: &tokio_postgres::Config) -> Result<Listener, String> {
    let (client, mut conn) = cfg.connect(NoTls).await.map_err(|e| e.to_string())?;
    let mut messages: Messages = Box::pin(futures_util::stream::poll_fn(move |cx| {
        conn.poll_message(cx)
    }));
    let mut early = Vec::new();
    {
        let sql = format!("LISTEN {CHANNEL}");
        let listen = client.batch_execute(&sql);
        tokio::pin!(listen);
        loop {
            tokio::select! {
                r = &mut listen => {
                    r.map_err(|e| e.to_string())?;
                    break;
                }
                m = messages.next() => match m {
                    Some(Ok(AsyncMessage::Notification(n))) => early.push(n),
                    Some(Ok(_)) => {}
                    Some(Err(e)) => return Err(e.to_string()),
                    None => return Err("connection closed".into()),
                },
            }
        }
    }
    Ok(Listener {
        _client: client,
        messages,
        early,
    })
}

pub(super) fn forward(tx: &broadcast::Sender<Notice>, n: &tokio_postgres::Notification) {
    match serde_json::from_str::<Notice>(n.payload()) {
        // No subscriber is not an error.
        Ok(notice) => drop(tx.send(notice)),
        Err(e) => tracing::warn!(payload = n.payload(), error = %e, "undecodable job store notice"),
    }
}

/// Forwards notices until the store is dropped (which aborts this task), reconnecting whenever
/// the connection is lost.
pub(super) async fn run_listener(
    cfg: tokio_postgres::Config,
    tx: broadcast::Sender<Notice>,
    mut listener: Listener,
) {
    loop {
        for n in std::mem::take(&mut listener.early) {
            forward(&tx, &n);
        }
        loop {
            match listener.messages.next().await {
                Some(Ok(AsyncMessage::Notification(n))) => forward(&tx, &n),
                Some(Ok(_)) => {}
                Some(Err(e)) => {
                    tracing::warn!(error = %e, "job store: notice connection lost");
                    break;
                }
                None => {
                    tracing::warn!("job store: notice connection closed");
                    break;
                }
            }
        }
        drop(listener);
        let mut delay = Duration::from_millis(100);
        listener = loop {
            tokio::time::sleep(delay).await;
            match listen(&cfg).await {
                Ok(l) => break l,
                Err(e) => {
                    tracing::debug!(error = %e, "job store: notice connection not back yet");
                    delay = (delay * 2).min(Duration::from_secs(1));
                }
            }
        };
        tracing::info!("job store: notice connection back");
        drop(tx.send(Notice::Resync));
    }
}
