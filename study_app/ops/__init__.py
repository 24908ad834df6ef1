"""Running the study at scale: replicas behind nginx on one PostgreSQL (:mod:`.replicas`)
and the load test's simulated participants (:mod:`.loadtest`).

Starts the servers of :mod:`study_app.web` as processes; imported only by the commands.
"""
