from hrc.service import exit_now

from hrc_logger.main import main

# hrc run starts the services as `python -m`: end at once when done (hrc.service.exit_now)
exit_now(main())
