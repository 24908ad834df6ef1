"""What a study stores, and every SQL statement it runs: the tables and database URLs
(:mod:`.database`), the store of participants, responses and events (:mod:`.store`, made of
:mod:`.engine`, :mod:`.participant_records`, :mod:`.response_records`, :mod:`.event_records`
and :mod:`.researcher_queries`, with :mod:`.rows` checks and :mod:`.group_commit`), withdrawal (:mod:`.withdraw`) and its log outside the database (:mod:`.withdrawal_log`), pseudonyms
(:mod:`.pseudonym`) and their end (:mod:`.anonymise`), backups (:mod:`.backup`), the export codec (:mod:`.export`), the
Psych-DS dataset (:mod:`.psychds`) and the one exception (:mod:`.errors`).

Imports :mod:`study_app.design` and snapcore, never the session, the UI or the commands;
``tests/test_architecture.py`` checks that no SQL appears outside this package.
"""
