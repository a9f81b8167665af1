"""Use a malcolm Process from ordinary (blocking) Python code.

A :class:`~malcolm.core.Process` lives on one asyncio loop. Scripts, GUIs and
test harnesses usually have no loop of their own, so :class:`ThreadedProcess`
runs the loop in a background thread and offers blocking calls that may be
made from any other thread::

    from malcolm.demo import demo_process
    from malcolm.embed import start_process

    with start_process(demo_process()) as tp:
        hello = tp.block("HELLO")
        print(hello.greet(name="me"))          # {'greeting': 'Hello me'}
        counter = tp.block("COUNTER")
        counter.counter.put(3)
        counter.increment()
        assert counter.counter.value == 4.0
        counter.state.when("Ready", timeout=5)

Errors raised by the process (``NotAllowedError``, ``BadValueError``,
``AbortedError``...) are raised again, unchanged, in the calling thread.
Subscription callbacks run in one dispatch thread of the ThreadedProcess, in
the order the changes happened, so a callback may itself make blocking calls.

For code that already runs on an asyncio loop, ``async with running(p):``
starts the process on the current loop and stops it on the way out.
"""

from .files import from_file
from .proxies import AttributeProxy, BlockProxy, MethodProxy
from .serving import running, serve, watch_states
from .threaded import SHUTDOWN_GRACE as SHUTDOWN_GRACE
from .threaded import EmbeddedSubscription, ThreadedProcess, start_process
from .threaded import log as log

# SHUTDOWN_GRACE and log are re-exported too: they were public names of the
# single-module malcolm.embed
__all__ = [
    "AttributeProxy",
    "BlockProxy",
    "EmbeddedSubscription",
    "MethodProxy",
    "ThreadedProcess",
    "from_file",
    "running",
    "serve",
    "start_process",
    "watch_states",
]
