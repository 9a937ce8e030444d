"""The perception study of ``experiment=stimuli``: a jsPsych page, responses in SQLite, a mixed-model report.

``build`` (the study folder), ``server`` (``study serve``), ``db`` (the SQLite schema), ``analyze``
(the report), ``power`` (participants needed), ``design`` (who sees what), ``vendor`` (jsPsych from
npm), ``plots`` (the report's figures); the command line is ``cli``.
"""
