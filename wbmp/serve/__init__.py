"""``wbmp serve``: a local page to talk to the robot (docs/serve.md).

:mod:`wbmp.serve.corrections` reads corrections in words ("slower", 再低一点) and changes the last
motion's actions; :mod:`wbmp.serve.session` holds the session's motions, the bounded job queue
and the planning process (:mod:`wbmp.serve.worker`); :mod:`wbmp.serve.server` answers HTTP on
127.0.0.1 (the page is ``static/index.html``; its 3D view is the HTML replay of ``viz.html``).
"""
