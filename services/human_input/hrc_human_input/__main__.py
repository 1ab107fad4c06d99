from hrc.service import exit_now

from hrc_human_input.main import main

# hrc run starts the services as `python -m`: end at once when done (hrc.service.exit_now)
exit_now(main())
