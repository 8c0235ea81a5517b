"""The studies, grouped by the question each answers: ``transfer`` (C8, C9 and what explains them),
``bus`` (C1-C5), ``races`` (C10, C11, X2), ``wildfire`` (C6, C7; evaluation and rendering),
``advantage`` (X1), ``bench`` (the engines' and the learner's speed) and ``training`` (train one
policy, plot runs). A study module is its command (``add_arguments`` and ``run(args, folders)``,
its folders resolved once by the command line: :class:`repro.studies.kit.options.Folders`); what
several studies of a group share lives in the group's ``study`` module, what every group shares in
``kit``.
"""
