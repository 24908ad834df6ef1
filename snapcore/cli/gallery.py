"""``snapshot gallery``: serve a batch's gallery so that thumbnail choices save at once."""

from __future__ import annotations

import click

__all__ = ["gallery"]


@click.command()
@click.argument("out", type=click.Path(file_okay=False, exists=True), metavar="OUT/")
@click.option(
    "--port",
    type=click.IntRange(0, 65535),
    default=8765,
    show_default=True,
    help="Port to listen on (0: any free one).",
)
@click.option(
    "--host",
    default="127.0.0.1",
    show_default=True,
    help="Address to listen on (the default is this machine only).",
)
def gallery(out, port, host):
    """Serve the gallery of `snapshot batch ... -o OUT` at http://HOST:PORT/.

    The page is the one in OUT/index.html (it also works opened from disk); served,
    a frame chosen as a scene's thumbnail is written into OUT/thumb-choices.csv at
    once, with every earlier choice kept. The next `snapshot batch` into OUT renders
    the chosen frames. Ctrl-C stops the server.
    """
    from snapcore.batch.serve import gallery_server

    server = gallery_server(out, host=host, port=port)
    h, p = server.server_address[:2]
    click.echo(f"gallery of {out} at http://{h}:{p}/ (Ctrl-C stops)")
    try:
        server.serve_forever()
    except KeyboardInterrupt:
        pass
    finally:
        server.server_close()
