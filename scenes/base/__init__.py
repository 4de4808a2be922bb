"""The pure base layer every layer may import (``metrics`` imports only this): atomic file
writes (:mod:`.files`), JSON-ready records and package versions (:mod:`.records`), the display
transform (:mod:`.display`), the one array check (:mod:`.arrays`) and untrusted input and
output text (:mod:`.untrusted`: bounded regular-file reads, path containment, field checks,
escaping). It imports nothing of the project and never Mitsuba or Dr.Jit."""
