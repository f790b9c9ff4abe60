"""`trials serve`: the field-day web console for running a study (run sheet, run pages, score form,
participants' questionnaire, progress), writing every file through the module that owns it."""
