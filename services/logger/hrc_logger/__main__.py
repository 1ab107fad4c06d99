from hrc.service import exit_now

from hrc_logger.main import main
from hrc_logger.nopandas import block_pandas

block_pandas()  # pyarrow's pandas import costs 0.2 CPU-s for nothing (hrc_logger.nopandas)
# hrc run starts the services as `python -m`: end at once when done (hrc.service.exit_now)
exit_now(main())
