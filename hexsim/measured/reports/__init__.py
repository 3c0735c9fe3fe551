"""The measured-data loop's reports, apart from the numbers they show: the validation's (``hexsim validate
--report``: report.md, residuals.png), the calibration's (``hexsim calibrate``: the table, report.md,
features.png), the friction map's (``hexsim friction --plot``) and the commissioning loop's (``hexsim tune --check``,
``--from-logs``). Each reads the JSON-able document its
command returns (and, for a figure, the arrays behind it); none computes a verdict or a fit.
"""
